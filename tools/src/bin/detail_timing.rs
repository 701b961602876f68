//! Times the detail's pieces at 1024^2 (`cargo run --release -p terrasketch-tools --bin detail_timing`).
fn main() {
    let n = 1024;
    let m = n / 4;
    let amp = vec![10.0f32; m * m];
    let t = std::time::Instant::now();
    let d = terrasketch_detail::detail_field(n, [10240.0, 10240.0], &amp, 1);
    println!(
        "detail_field {n}: {:.1} ms ({})",
        t.elapsed().as_secs_f64() * 1e3,
        d[12345]
    );
    let mip2: Vec<f32> = (0..m * m).map(|k| (k % 97) as f32).collect();
    let rough = vec![0.5f32; m * m];
    let counts: Vec<u32> = (0..m * m).map(|k| u32::from(k % 31 == 0)).collect();
    for _ in 0..3 {
        let t = std::time::Instant::now();
        let a = terrasketch_detail::amplitude_map(&terrasketch_detail::AmplitudeInputs {
            m,
            cell_m: [40.0, 40.0],
            mip2: &mip2,
            roughness: &rough,
            hard_counts: &counts,
        });
        println!(
            "amplitude_map {m}: {:.2} ms ({})",
            t.elapsed().as_secs_f64() * 1e3,
            a[77]
        );
    }
}

fn main() {
    let n = 1024;
    let amp = vec![10.0f32; (n / 4) * (n / 4)];
    let t = std::time::Instant::now();
    let d = terrasketch_detail::detail_field(n, [10240.0, 10240.0], &amp, 1);
    println!(
        "detail_field {n}: {:.1} ms ({})",
        t.elapsed().as_secs_f64() * 1e3,
        d[12345]
    );
}

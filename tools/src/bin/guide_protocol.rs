//! Scott & Dodgson's guide-reproduction protocol on the shipped exemplars, leave-one-out.
//!
//! `cargo run --release -p terrasketch-tools --bin guide_protocol -- [--seed S]
//! [--only NAME] [--hillshades DIR] [--cache-dir DIR] [--levels L] [--band CELLS]
//! [--guide-weight A] [--lowpass CELLS] [--low-weight W] [--reuse W] [--fine-detail G] [--fill-pits]
//! [--spectrum]`
//!
//! Each DEM, at its own cell size and cropped to a centred power-of-two square (at most 1024),
//! is rebuilt from its 16x block-averaged, B-spline-upsampled guide with the four other DEMs as
//! exemplars. Prints one table per DEM (real, guide, refined) and the targets met; with
//! `--spectrum` also the guide's and the refined terrain's power per octave of wavelength over the
//! real DEM's (1 = real land's relief at that scale). `--lowpass`, `--low-weight`, `--reuse`,
//! `--fine-detail` and `--fill-pits` set `RefineParams::lowpass_cells`, `low_weight`,
//! `weights.reuse`, `fine_detail` and a filling `pit_mode`.
//!
//! `guide_protocol --hillshade-of DEM PNG` writes the hillshade of any DEM or heightmap file.

use std::path::PathBuf;
use std::process::ExitCode;

use terrasketch_synthesis::metrics::Metrics;
use terrasketch_synthesis::protocol::{Reproduction, hillshade, reproduce, write_grey_png};
use terrasketch_synthesis::refine::RefineParams;
use terrasketch_synthesis::{LoadOptions, load_dem, load_exemplar_dir, shipped_exemplar_dir};

struct Args {
    hillshade_of: Option<(PathBuf, PathBuf)>,
    seed: u64,
    only: Option<String>,
    hillshades: Option<PathBuf>,
    cache_dir: Option<PathBuf>,
    spectrum: bool,
    params: RefineParams,
}

fn parse() -> Result<Args, String> {
    let mut a = Args {
        hillshade_of: None,
        seed: 1,
        only: None,
        hillshades: None,
        spectrum: false,
        params: RefineParams::default(),
        cache_dir: std::env::var_os("HOME")
            .map(|h| PathBuf::from(h).join(".cache/terrasketch/features")),
    };
    let mut it = std::env::args().skip(1);
    while let Some(k) = it.next() {
        let mut val = || it.next().ok_or_else(|| format!("{k} needs a value"));
        match k.as_str() {
            "--seed" => a.seed = val()?.parse().map_err(|e| format!("--seed: {e}"))?,
            "--only" => a.only = Some(val()?),
            "--levels" => a.params.levels = val()?.parse().map_err(|e| format!("--levels: {e}"))?,
            "--band" => {
                a.params.level_band_cells = val()?.parse().map_err(|e| format!("--band: {e}"))?
            }
            "--guide-weight" => {
                a.params.guide_weight =
                    val()?.parse().map_err(|e| format!("--guide-weight: {e}"))?
            }
            "--spectrum" => a.spectrum = true,
            "--reuse" => {
                a.params.weights.reuse = val()?.parse().map_err(|e| format!("--reuse: {e}"))?
            }
            "--fine-detail" => {
                a.params.fine_detail = val()?.parse().map_err(|e| format!("--fine-detail: {e}"))?
            }
            "--low-weight" => {
                a.params.low_weight = val()?.parse().map_err(|e| format!("--low-weight: {e}"))?
            }
            "--lowpass" => {
                a.params.lowpass_cells = val()?.parse().map_err(|e| format!("--lowpass: {e}"))?
            }
            "--fill-pits" => {
                a.params.pit_mode = terrasketch_synthesis::pits::PitMode::Fill { epsilon: true }
            }
            "--hillshades" => a.hillshades = Some(PathBuf::from(val()?)),
            "--cache-dir" => a.cache_dir = Some(PathBuf::from(val()?)),
            "--hillshade-of" => {
                let input = PathBuf::from(val()?);
                a.hillshade_of = Some((input, PathBuf::from(val()?)));
            }
            _ => return Err(format!("unknown argument {k}")),
        }
    }
    Ok(a)
}

fn main() -> ExitCode {
    let args = match parse() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("guide_protocol: {e}");
            return ExitCode::FAILURE;
        }
    };
    if let Some((input, out)) = &args.hillshade_of {
        return match load_dem(input, &LoadOptions::default()) {
            Ok(d) => {
                let px = hillshade(&d.heights_m, d.width, d.height, d.cell_size_m);
                match write_grey_png(out, &px, d.width, d.height) {
                    Ok(()) => ExitCode::SUCCESS,
                    Err(e) => {
                        eprintln!("guide_protocol: cannot write {}: {e}", out.display());
                        ExitCode::FAILURE
                    }
                }
            }
            Err(e) => {
                eprintln!("guide_protocol: {}: {e}", input.display());
                ExitCode::FAILURE
            }
        };
    }
    let (dems, failures) = load_exemplar_dir(&shipped_exemplar_dir());
    for (p, e) in failures {
        eprintln!("guide_protocol: {} skipped: {e}", p.display());
    }
    let params = RefineParams {
        seed: args.seed,
        ..args.params.clone()
    };
    let mut failed = false;
    for i in 0..dems.len() {
        if args
            .only
            .as_ref()
            .is_some_and(|o| !dems[i].name.contains(o.as_str()))
        {
            continue;
        }
        let r = match reproduce(&dems, i, &params, args.cache_dir.as_deref()) {
            Ok(r) => r,
            Err(e) => {
                eprintln!("guide_protocol: {}: {e}", dems[i].name);
                failed = true;
                continue;
            }
        };
        print_measures(&r, args.seed);
        if args.spectrum {
            print_spectrum(&r.metrics);
        }
        if let Some(dir) = &args.hillshades {
            let n = r.side;
            for (tag, h) in [
                ("real", &r.real),
                ("guide", &r.guide),
                ("refined", &r.refined),
            ] {
                let path = dir.join(format!("{}_{tag}.png", r.name));
                let px = hillshade(h, n, n, r.cell_size_m);
                if let Err(e) = write_grey_png(&path, &px, n, n) {
                    eprintln!("guide_protocol: cannot write {}: {e}", path.display());
                    failed = true;
                }
            }
        }
    }
    if failed {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
}

/// Power per octave of wavelength of the guide and the refined terrain over the real DEM's.
fn print_spectrum([real, guide, refined]: &[Metrics; 3]) {
    println!("\n| wavelengths (m) | real power (m^2) | guide / real | refined / real |");
    println!("|---|---|---|---|");
    let octaves = real.octave_power.iter().zip(&guide.octave_power);
    for ((r, g), o) in octaves.zip(&refined.octave_power) {
        let ratio = |p: f64| p / r.power_m2.max(1e-30);
        println!(
            "| {:.0}-{:.0} | {:.3e} | {:.3} | {:.3} |",
            r.longest_m,
            r.shortest_m,
            r.power_m2,
            ratio(g.power_m2),
            ratio(o.power_m2)
        );
    }
}

/// One DEM's table: each measure on the real DEM, its guide and the refined terrain, and the
/// protocol's target.
fn print_measures(r: &Reproduction, seed: u64) {
    let [real, guide, out] = &r.metrics;
    println!(
        "\n### {} ({}^2 at {:.1} x {:.1} m, refine {:.1} s, seed {})\n",
        r.name,
        r.side,
        r.cell_size_m[0],
        r.cell_size_m[1],
        r.ms_refine / 1e3,
        seed
    );
    println!("| measure | real | guide | refined | target | met |");
    println!("|---|---|---|---|---|---|");
    let [w_g, w_o] = r.slope_w1_deg;
    let ok = |b: bool| if b { "yes" } else { "no" };
    println!(
        "| slope W1 to real (deg) | 0 | {w_g:.2} | {w_o:.2} | <= 0.5 x guide ({:.2}) | {} |",
        w_o / w_g.max(1e-9),
        ok(w_o <= 0.5 * w_g)
    );
    // A measure whose target is the real value within a relative band.
    let within = |name: &str, of: fn(&Metrics) -> f64, band: f64| {
        let (want, got) = (of(real), of(out));
        let rel = (got - want) / want.abs().max(1e-9);
        println!(
            "| {name} | {want:.3} | {:.3} | {got:.3} | +-{:.0}% ({:+.0}%) | {} |",
            of(guide),
            100.0 * band,
            100.0 * rel,
            ok(rel.abs() <= band)
        );
    };
    within("roughness_cv", |m| m.roughness_cv, 0.25);
    within("flat_fraction", |m| m.flat_fraction, 0.30);
    let ax = |m: &Metrics| m.axis_ratio.unwrap_or(f64::NAN);
    println!(
        "| axis_ratio | {:.2} | {:.2} | {:.2} | <= 1.25 | {} |",
        ax(real),
        ax(guide),
        ax(out),
        ok(ax(out) <= 1.25)
    );
    let sp = |m: &Metrics| m.spectral_slope.unwrap_or(f64::NAN);
    println!(
        "| spectral slope | {:.2} | {:.2} | {:.2} | +-0.3 | {} |",
        sp(real),
        sp(guide),
        sp(out),
        ok((sp(out) - sp(real)).abs() <= 0.3)
    );
    println!(
        "| pits >10 m per 100 km^2 | {:.1} | {:.1} | {:.1} | <= exemplars' {:.1} | {} |",
        real.pits_per_100km2,
        guide.pits_per_100km2,
        out.pits_per_100km2,
        r.exemplar_pits_per_100km2,
        ok(out.pits_per_100km2 <= r.exemplar_pits_per_100km2)
    );
    println!(
        "| trenches | {} | {} | {} | | |",
        real.trenches, guide.trenches, out.trenches
    );
    println!(
        "| slope mean (deg) | {:.1} | {:.1} | {:.1} | | |",
        real.slope_mean_deg, guide.slope_mean_deg, out.slope_mean_deg
    );
}

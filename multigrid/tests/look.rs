//! What the solved terrain looks like (CPU, converged): smooth strokes leave no facets, eased slopes
//! leave no crease at the band edge. Each test also checks the old shape (polylines with a constant
//! slope to the band edge), so that it can fail.

mod look_common;

use look_common::*;

/// A 12-point circular ridge (radius 50 cells, band 37.5 cells, 256^2): along the circles at half
/// the band width, no aspect step between neighbouring samples exceeds 3 times the median step
/// (everywhere when closed, away from the join when open). The polygon of 12 throws facets.
#[test]
fn a_circular_ridge_has_no_facets() {
    let (n, r, w) = (256, 50.0, 37.5);
    for closed in [true, false] {
        for old in [false, true] {
            let mut sketch = circle_sketch(n, 12, r, w, closed);
            if old {
                old_shape(&mut sketch);
            }
            let (h, _) = solve(&sketch, n);
            for radius in [r + 0.5 * w, r - 0.5 * w] {
                let skip = if closed && !old {
                    0.0
                } else {
                    2.0 * std::f64::consts::TAU / 12.0
                };
                let (ratio, median, max) = facet_ratio(&aspect_steps(&h, n, radius), skip);
                eprintln!(
                    "closed {closed} old {old} radius {radius}: ratio {ratio:.2} (median {median:.4}, max {max:.4} deg)"
                );
                if old {
                    assert!(ratio > 10.0, "the polygon's facets are not seen: {ratio}");
                } else {
                    assert!(
                        ratio <= 3.0,
                        "closed {closed} radius {radius}: ratio {ratio}"
                    );
                }
            }
        }
    }
}

/// The example sketch at 1024^2 (the measured figure; at 256^2 the drop is only 3-fold, the cells are
/// 4 times coarser against the bands): the 99.9th percentile of |Laplacian| more than 2 cells from every
/// hard constraint is at least 5 times lower than with the old shape (the crease along every band
/// edge).
#[test]
fn band_edges_leave_no_crease() {
    let n = 1024;
    let sketch = terrasketch_sketch::example_sketch();
    let mut old = sketch.clone();
    old_shape(&mut old);
    let (h, w) = solve(&sketch, n);
    let (p_new, max_new, _) = laplacian_away_from_hard(&h, &w, n, 2);
    let (h, w) = solve(&old, n);
    let (p_old, max_old, _) = laplacian_away_from_hard(&h, &w, n, 2);
    eprintln!("p99.9 |L| {p_old:.3} -> {p_new:.3} m, max {max_old:.3} -> {max_new:.3} m");
    assert!(p_new * 5.0 <= p_old, "{p_old} -> {p_new}");
}

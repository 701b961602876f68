//! Tests of the stencil records' decoding.

use super::reads::{snorm, unpack_stencils};
use super::*;

/// The record `st_record` writes, in Rust (`pack2x16snorm`: `round(32767 clamp(v, -1, 1))`).
fn pack(c: [f32; 9]) -> [u32; STENCIL_WORDS] {
    let off = [c[0], c[1], c[2], c[3], c[5], c[6], c[7], c[8]];
    let scale = off.iter().fold(0.0f32, |m, v| m.max(v.abs()));
    let sum = c[4] + (((c[0] + c[1]) + (c[2] + c[3])) + ((c[5] + c[6]) + (c[7] + c[8])));
    let inv = if scale > 0.0 { 1.0 / scale } else { 0.0 };
    let h = |v: f32| u32::from(((v * inv).clamp(-1.0, 1.0) * 32767.0).round() as i16 as u16);
    let pair = |a: f32, b: f32| h(a) | h(b) << 16;
    [
        pair(c[0], c[1]),
        pair(c[2], c[3]),
        pair(c[5], c[6]),
        pair(c[7], c[8]),
        sum.to_bits(),
        scale.to_bits(),
    ]
}

/// Decoded stencils keep their row sums to f32 rounding and move each off-centre coefficient
/// by at most 1 / 65534 of the row's largest (the largest itself comes back exactly); an
/// all-zero record (inactive cell) decodes to an exactly zero centre.
#[test]
fn records_keep_row_sums_and_round_coefficients_to_snorm16() {
    let rows: [[f32; 9]; 4] = [
        [
            -0.0625, -0.375, -0.0625, -0.375, 2.5625, -0.375, -0.0625, -0.375, -0.0625,
        ],
        [
            -0.1, -0.2, 0.013, -0.31, 3996.7, -1.7e-3, -0.29, -0.33, -0.07,
        ],
        [
            -1.3e-5, -2.2e-5, -0.9e-5, -3.1e-5, 1.5e-4, -3.3e-5, -2.9e-5, -3.0e-5, -1.1e-5,
        ],
        [-7.0, -0.1, 0.0, -6.9, 31.0, -6.95, -0.12, -7.01, -0.05],
    ];
    for c in rows {
        let d = unpack_stencils(&pack(c))[0];
        let scale = [c[0], c[1], c[2], c[3], c[5], c[6], c[7], c[8]]
            .iter()
            .fold(0.0f32, |m, v| m.max(v.abs()));
        for k in (0..9).filter(|&k| k != 4) {
            assert!(
                (d[k] - c[k]).abs() <= scale / 65534.0 * 1.001,
                "{c:?}: coefficient {k} {} -> {}",
                c[k],
                d[k]
            );
        }
        let sum = |s: &[f32; 9]| s.iter().map(|&v| f64::from(v)).sum::<f64>();
        let rel = (sum(&d) - sum(&c)).abs() / f64::from(c[4]);
        assert!(
            rel <= 1e-6,
            "{c:?}: row sum moved by {rel:.1e} of the centre"
        );
    }
    let exact = [0.0, -0.375, 0.0, -0.375, 1.5, -0.375, 0.0, -0.375, 0.0];
    assert_eq!(unpack_stencils(&pack(exact))[0], exact);
    assert_eq!(snorm(0x8000), -1.0);
    assert_eq!(snorm(0x7fff), 1.0);
    assert_eq!(unpack_stencils(&[0; STENCIL_WORDS])[0][4], 0.0);
    assert_eq!(unpack_stencils(&[0; 3 * STENCIL_WORDS]).len(), 3);
}

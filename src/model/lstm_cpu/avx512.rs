//! The AVX-512 kernel of the batched matrix product (x86-64).

use super::{MC, NR};
use std::arch::x86_64::*;

/// Rows of the full tile (8 rows × 2 blocks: 16 accumulators).
const MR: usize = 8;

/// `y[r] += W x[r]` (see `super::gemm`; sizes checked there), the AVX2 driver's shape
/// with 16-lane registers: one register per packed row of a block.
#[allow(clippy::too_many_arguments)]
#[target_feature(enable = "avx512f")]
pub unsafe fn gemm(
    w: *const f32,
    k: usize,
    n: usize,
    x: *const f32,
    ldx: usize,
    rows: usize,
    y: *mut f32,
    ldy: usize,
) {
    let nb = n / NR;
    let step = k * NR;
    let mut r0 = 0;
    while r0 < rows {
        let mc = MC.min(rows - r0);
        let full = mc / MR * MR;
        if full > 0 {
            blocks::<MR, 2>(
                w,
                step,
                nb,
                k,
                full,
                x.add(r0 * ldx),
                ldx,
                y.add(r0 * ldy),
                ldy,
            );
        }
        let (r, rest) = (r0 + full, mc - full);
        let (xr, yr) = (x.add(r * ldx), y.add(r * ldy));
        match rest {
            0 => {}
            1 => blocks::<1, 8>(w, step, nb, k, 1, xr, ldx, yr, ldy),
            2 => blocks::<2, 4>(w, step, nb, k, 2, xr, ldx, yr, ldy),
            3 => blocks::<3, 4>(w, step, nb, k, 3, xr, ldx, yr, ldy),
            4 => blocks::<4, 2>(w, step, nb, k, 4, xr, ldx, yr, ldy),
            5 => blocks::<5, 2>(w, step, nb, k, 5, xr, ldx, yr, ldy),
            6 => blocks::<6, 2>(w, step, nb, k, 6, xr, ldx, yr, ldy),
            _ => blocks::<7, 2>(w, step, nb, k, 7, xr, ldx, yr, ldy),
        }
        r0 += mc;
    }
}

/// `rows` rows (a multiple of `R`) over every column block, `B` blocks a tile (one
/// block a tile at the end); each group of blocks passes over all the rows while its
/// weights stay in L1.
#[allow(clippy::too_many_arguments)]
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn blocks<const R: usize, const B: usize>(
    w: *const f32,
    step: usize,
    nb: usize,
    k: usize,
    rows: usize,
    x: *const f32,
    ldx: usize,
    y: *mut f32,
    ldy: usize,
) {
    let mut b = 0;
    while b < nb {
        let wide = b + B <= nb;
        let mut r = 0;
        while r < rows {
            let (xr, yr) = (x.add(r * ldx), y.add(r * ldy + b * NR));
            if wide {
                tile::<R, B>(w.add(b * step), step, k, xr, ldx, yr, ldy);
            } else {
                tile::<R, 1>(w.add(b * step), step, k, xr, ldx, yr, ldy);
            }
            r += R;
        }
        b += if wide { B } else { 1 };
    }
}

/// The register tile: `R` rows × `B` packed blocks of 16 outputs, `R·B` accumulators
/// loaded from y, `k` rank-1 updates, stored back.
#[allow(clippy::too_many_arguments, clippy::needless_range_loop)] // acc[r][b]: registers, clearer indexed
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn tile<const R: usize, const B: usize>(
    w: *const f32,
    step: usize,
    k: usize,
    x: *const f32,
    ldx: usize,
    y: *mut f32,
    ldy: usize,
) {
    let mut acc = [[_mm512_setzero_ps(); B]; R];
    for r in 0..R {
        for b in 0..B {
            acc[r][b] = _mm512_loadu_ps(y.add(r * ldy + b * NR));
        }
    }
    for kk in 0..k {
        let mut wv = [_mm512_setzero_ps(); B];
        for b in 0..B {
            wv[b] = _mm512_loadu_ps(w.add(b * step + kk * NR));
        }
        for r in 0..R {
            let xv = _mm512_set1_ps(*x.add(r * ldx + kk));
            for b in 0..B {
                acc[r][b] = _mm512_fmadd_ps(wv[b], xv, acc[r][b]);
            }
        }
    }
    for r in 0..R {
        for b in 0..B {
            _mm512_storeu_ps(y.add(r * ldy + b * NR), acc[r][b]);
        }
    }
}

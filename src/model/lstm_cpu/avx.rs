//! The AVX2 + FMA kernel of the batched matrix product (x86-64).

use super::{MC, MR, NR};
use std::arch::x86_64::*;

/// `y[r] += W x[r]` (see `super::gemm`; sizes checked there). Rows in chunks of `MC`;
/// in each, every column block runs over the chunk's full 6-row tiles, then the rows
/// left over (fewer than 6) over several blocks at a time.
#[allow(clippy::too_many_arguments)]
#[target_feature(enable = "avx2,fma")]
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
    let step = k * NR; // floats from one packed block to the next
    let mut r0 = 0;
    while r0 < rows {
        let mc = MC.min(rows - r0);
        let full = mc / MR * MR;
        for b in 0..nb {
            let (wb, mut r) = (w.add(b * step), r0);
            while r < r0 + full {
                tile::<MR, 1>(
                    wb,
                    step,
                    k,
                    x.add(r * ldx),
                    ldx,
                    y.add(r * ldy + b * NR),
                    ldy,
                );
                r += MR;
            }
        }
        let (r, rest) = (r0 + full, mc - full);
        let (xr, yr) = (x.add(r * ldx), y.add(r * ldy));
        match rest {
            0 => {}
            1 => blocks::<1, 4>(w, step, nb, k, xr, ldx, yr, ldy),
            2 => blocks::<2, 2>(w, step, nb, k, xr, ldx, yr, ldy),
            3 => blocks::<3, 2>(w, step, nb, k, xr, ldx, yr, ldy),
            4 => blocks::<4, 1>(w, step, nb, k, xr, ldx, yr, ldy),
            _ => blocks::<5, 1>(w, step, nb, k, xr, ldx, yr, ldy),
        }
        r0 += mc;
    }
}

/// `R` rows over every column block, `B` blocks a tile (one block a tile at the end).
#[allow(clippy::too_many_arguments)]
#[inline]
#[target_feature(enable = "avx2,fma")]
unsafe fn blocks<const R: usize, const B: usize>(
    w: *const f32,
    step: usize,
    nb: usize,
    k: usize,
    x: *const f32,
    ldx: usize,
    y: *mut f32,
    ldy: usize,
) {
    let mut b = 0;
    while b + B <= nb {
        tile::<R, B>(w.add(b * step), step, k, x, ldx, y.add(b * NR), ldy);
        b += B;
    }
    while b < nb {
        tile::<R, 1>(w.add(b * step), step, k, x, ldx, y.add(b * NR), ldy);
        b += 1;
    }
}

/// The register tile: `R` rows × `B` packed blocks of 16 outputs, `2·R·B` accumulators
/// loaded from y, `k` rank-1 updates, stored back.
#[allow(clippy::too_many_arguments, clippy::needless_range_loop)] // acc[r][b][q]: registers, clearer indexed
#[inline]
#[target_feature(enable = "avx2,fma")]
unsafe fn tile<const R: usize, const B: usize>(
    w: *const f32,
    step: usize,
    k: usize,
    x: *const f32,
    ldx: usize,
    y: *mut f32,
    ldy: usize,
) {
    let mut acc = [[[_mm256_setzero_ps(); 2]; B]; R];
    for r in 0..R {
        for b in 0..B {
            for q in 0..2 {
                acc[r][b][q] = _mm256_loadu_ps(y.add(r * ldy + b * NR + 8 * q));
            }
        }
    }
    for kk in 0..k {
        let mut wv = [[_mm256_setzero_ps(); 2]; B];
        for b in 0..B {
            for q in 0..2 {
                wv[b][q] = _mm256_loadu_ps(w.add(b * step + kk * NR + 8 * q));
            }
        }
        for r in 0..R {
            let xv = _mm256_set1_ps(*x.add(r * ldx + kk));
            for b in 0..B {
                for q in 0..2 {
                    acc[r][b][q] = _mm256_fmadd_ps(wv[b][q], xv, acc[r][b][q]);
                }
            }
        }
    }
    for r in 0..R {
        for b in 0..B {
            for q in 0..2 {
                _mm256_storeu_ps(y.add(r * ldy + b * NR + 8 * q), acc[r][b][q]);
            }
        }
    }
}

/// e^x for 8 lanes (Cephes' single-precision polynomial, ~1 ulp on [-88, 88]).
#[inline]
#[target_feature(enable = "avx2,fma")]
unsafe fn exp(x: __m256) -> __m256 {
    let x = _mm256_min_ps(
        _mm256_max_ps(x, _mm256_set1_ps(-87.3)),
        _mm256_set1_ps(88.3),
    );
    let n = _mm256_round_ps(
        _mm256_mul_ps(x, _mm256_set1_ps(std::f32::consts::LOG2_E)),
        _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC,
    );
    let r = _mm256_fnmadd_ps(n, _mm256_set1_ps(0.693_359_4), x);
    let r = _mm256_fnmadd_ps(n, _mm256_set1_ps(-2.121_944_4e-4), r);
    let mut p = _mm256_set1_ps(1.987_569_1e-4);
    for c in [
        1.398_199_9e-3,
        8.333_452e-3,
        4.166_579_6e-2,
        1.666_666_5e-1,
        0.5,
    ] {
        p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(c));
    }
    let p = _mm256_add_ps(
        _mm256_fmadd_ps(_mm256_mul_ps(p, r), r, r),
        _mm256_set1_ps(1.0),
    );
    let scale = _mm256_castsi256_ps(_mm256_slli_epi32(
        _mm256_add_epi32(_mm256_cvtps_epi32(n), _mm256_set1_epi32(127)),
        23,
    ));
    _mm256_mul_ps(p, scale)
}

#[inline]
#[target_feature(enable = "avx2,fma")]
unsafe fn sigmoid(x: __m256) -> __m256 {
    let one = _mm256_set1_ps(1.0);
    _mm256_div_ps(
        one,
        _mm256_add_ps(one, exp(_mm256_sub_ps(_mm256_setzero_ps(), x))),
    )
}

/// tanh x = 2σ(2x) − 1.
#[inline]
#[target_feature(enable = "avx2,fma")]
unsafe fn tanh(x: __m256) -> __m256 {
    let s = sigmoid(_mm256_add_ps(x, x));
    _mm256_sub_ps(_mm256_add_ps(s, s), _mm256_set1_ps(1.0))
}

#[target_feature(enable = "avx2,fma")]
pub unsafe fn cell(gates: &[f32], c: &mut [f32], h: &mut [f32]) {
    let hd = h.len();
    assert!(gates.len() >= 4 * hd && c.len() >= hd);
    let g = gates.as_ptr();
    for j in (0..hd).step_by(8) {
        let i = sigmoid(_mm256_loadu_ps(g.add(j)));
        let f = sigmoid(_mm256_loadu_ps(g.add(hd + j)));
        let gg = tanh(_mm256_loadu_ps(g.add(2 * hd + j)));
        let o = sigmoid(_mm256_loadu_ps(g.add(3 * hd + j)));
        let cn = _mm256_fmadd_ps(f, _mm256_loadu_ps(c.as_ptr().add(j)), _mm256_mul_ps(i, gg));
        _mm256_storeu_ps(c.as_mut_ptr().add(j), cn);
        _mm256_storeu_ps(h.as_mut_ptr().add(j), _mm256_mul_ps(o, tanh(cn)));
    }
}

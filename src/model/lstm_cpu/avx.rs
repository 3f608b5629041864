//! The AVX2 + FMA kernel of the batched matrix product (x86-64).

use super::{MC, MR, NR};
use std::arch::x86_64::*;

gemm_kernel! {
    feature: "avx2,fma",
    lanes: 8,
    ops: _mm256_setzero_ps, _mm256_loadu_ps, _mm256_storeu_ps, _mm256_set1_ps, _mm256_fmadd_ps,
    full: MR => 1,
    rest: 1 => 4, 2 => 2, 3 => 2, 4 => 1, else 5 => 1,
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

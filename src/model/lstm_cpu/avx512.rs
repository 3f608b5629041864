//! The AVX-512 kernels (x86-64): the batched matrix product, and the LSTM cell 16 lanes at a time.

use super::{MC, NR};
use std::arch::x86_64::*;

/// Rows of the full tile (8 rows × 2 blocks: 16 accumulators).
const MR: usize = 8;

gemm_kernel! {
    feature: "avx512f",
    lanes: 16,
    ops: _mm512_setzero_ps, _mm512_loadu_ps, _mm512_storeu_ps, _mm512_set1_ps, _mm512_fmadd_ps,
    full: MR => 2,
    rest: 1 => 8, 2 => 4, 3 => 4, 4 => 2, 5 => 2, 6 => 2, else 7 => 2,
}

/// e^x for 16 lanes: [`super::avx`]'s polynomial, the same operations in the same order
/// lane for lane, so the same bits (IEEE rounding of each operation does not depend on
/// the register's width).
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn exp(x: __m512) -> __m512 {
    let x = _mm512_min_ps(
        _mm512_max_ps(x, _mm512_set1_ps(-87.3)),
        _mm512_set1_ps(88.3),
    );
    let n = _mm512_roundscale_ps::<{ _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC }>(
        _mm512_mul_ps(x, _mm512_set1_ps(std::f32::consts::LOG2_E)),
    );
    let r = _mm512_fnmadd_ps(n, _mm512_set1_ps(0.693_359_4), x);
    let r = _mm512_fnmadd_ps(n, _mm512_set1_ps(-2.121_944_4e-4), r);
    let mut p = _mm512_set1_ps(1.987_569_1e-4);
    for c in [
        1.398_199_9e-3,
        8.333_452e-3,
        4.166_579_6e-2,
        1.666_666_5e-1,
        0.5,
    ] {
        p = _mm512_fmadd_ps(p, r, _mm512_set1_ps(c));
    }
    let p = _mm512_add_ps(
        _mm512_fmadd_ps(_mm512_mul_ps(p, r), r, r),
        _mm512_set1_ps(1.0),
    );
    let scale = _mm512_castsi512_ps(_mm512_slli_epi32::<23>(_mm512_add_epi32(
        _mm512_cvtps_epi32(n),
        _mm512_set1_epi32(127),
    )));
    _mm512_mul_ps(p, scale)
}

#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn sigmoid(x: __m512) -> __m512 {
    let one = _mm512_set1_ps(1.0);
    _mm512_div_ps(
        one,
        _mm512_add_ps(one, exp(_mm512_sub_ps(_mm512_setzero_ps(), x))),
    )
}

/// tanh x = 2σ(2x) − 1.
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn tanh(x: __m512) -> __m512 {
    let s = sigmoid(_mm512_add_ps(x, x));
    _mm512_sub_ps(_mm512_add_ps(s, s), _mm512_set1_ps(1.0))
}

/// The LSTM cell 16 lanes at a time (H a multiple of 16): bit for bit
/// [`super::avx::cell`]'s results, in half the instructions.
#[target_feature(enable = "avx512f")]
pub unsafe fn cell(gates: &[f32], c: &mut [f32], h: &mut [f32]) {
    let hd = h.len();
    assert!(gates.len() >= 4 * hd && c.len() >= hd && hd.is_multiple_of(16));
    let g = gates.as_ptr();
    for j in (0..hd).step_by(16) {
        let i = sigmoid(_mm512_loadu_ps(g.add(j)));
        let f = sigmoid(_mm512_loadu_ps(g.add(hd + j)));
        let gg = tanh(_mm512_loadu_ps(g.add(2 * hd + j)));
        let o = sigmoid(_mm512_loadu_ps(g.add(3 * hd + j)));
        let cn = _mm512_fmadd_ps(f, _mm512_loadu_ps(c.as_ptr().add(j)), _mm512_mul_ps(i, gg));
        _mm512_storeu_ps(c.as_mut_ptr().add(j), cn);
        _mm512_storeu_ps(h.as_mut_ptr().add(j), _mm512_mul_ps(o, tanh(cn)));
    }
}

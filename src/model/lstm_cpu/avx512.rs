//! The AVX-512 kernel of the batched matrix product (x86-64).

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

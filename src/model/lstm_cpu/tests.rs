//! Tests of the parent module.

use super::*;

#[test]
fn vector_exp_is_accurate() {
    if Isa::detect() < Isa::Avx2 {
        return;
    }
    let xs: Vec<f32> = (0..2000).map(|i| -40.0 + i as f32 * 0.04).collect();
    let (mut gates, mut c, mut h) = (vec![0.0f32; 32], vec![0.0f32; 8], vec![0.0f32; 8]);
    for chunk in xs.chunks(8) {
        // With i = σ(x), f = σ(x), g = tanh(x), o = σ(x) and c = 0: c' = σ(x)tanh(x).
        for q in 0..4 {
            gates[q * 8..q * 8 + 8].copy_from_slice(chunk);
        }
        c.iter_mut().for_each(|v| *v = 0.0);
        // SAFETY: AVX2 and FMA were detected.
        unsafe { avx::cell(&gates, &mut c, &mut h) };
        for (k, &x) in chunk.iter().enumerate() {
            let s = 1.0 / (1.0 + (-x as f64).exp());
            let want = s * (x as f64).tanh();
            assert!(
                (c[k] as f64 - want).abs() < 2e-7,
                "x = {x}: {} vs {want}",
                c[k]
            );
        }
    }
}

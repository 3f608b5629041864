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

/// The 16-lane cell gives the 8-lane cell's bits (the replay's output is byte for byte the
/// same whichever the CPU has), over the range the gates take and beyond (exp's clamps).
#[test]
fn avx512_cell_matches_avx2_bit_for_bit() {
    if Isa::detect() < Isa::Avx512 {
        return;
    }
    let hd = 64;
    let xs: Vec<f32> = (0..4 * hd * 50)
        .map(|i| ((i as f32) * 0.7311).sin() * (1.0 + (i % 97) as f32))
        .collect();
    for gates in xs.chunks_exact(4 * hd) {
        let c0: Vec<f32> = gates[..hd].iter().map(|v| v * 0.37).collect();
        let (mut c8, mut h8) = (c0.clone(), vec![0.0f32; hd]);
        let (mut c16, mut h16) = (c0, vec![0.0f32; hd]);
        // SAFETY: AVX-512F (and with it AVX2 and FMA on every CPU that has it) was detected.
        unsafe {
            avx::cell(gates, &mut c8, &mut h8);
            avx512::cell(gates, &mut c16, &mut h16);
        }
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&c8), bits(&c16));
        assert_eq!(bits(&h8), bits(&h16));
    }
}

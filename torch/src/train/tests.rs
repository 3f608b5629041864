//! Tests of `torch/src/train/mod.rs` (a file of their own: the module stays under 600 lines).

use super::*;

#[test]
fn relative_weights_average_one_in_flight_and_leave_the_ground_alone() {
    assert!(relative_weights(&[300.0, 500.0], 0.0).is_none());
    let y = [2.0f32, 60.0, 100.0, 250.0, 500.0];
    for lambda in [0.5, 1.0] {
        let w = relative_weights(&y, lambda).expect("weights");
        assert_eq!(
            &w[..2],
            &[1.0, 1.0],
            "ground windows keep the absolute loss"
        );
        let mean = w[2..].iter().map(|&v| f64::from(v)).sum::<f64>() / 3.0;
        assert!(
            (mean - 1.0).abs() < 1e-6,
            "λ {lambda}: in-flight mean weight {mean}"
        );
        assert!(w[2] > w[3] && w[3] > w[4], "λ {lambda}: {w:?}");
    }
    // λ = 1 is the relative error in flight: weight × power is constant.
    let w = relative_weights(&y, 1.0).expect("weights");
    assert!((w[3] * 250.0 - w[4] * 500.0).abs() < 1e-3);
    // λ = ½ keeps half the absolute loss: no window weighs under ½.
    let w = relative_weights(&y, 0.5).expect("weights");
    assert!(w.iter().all(|&v| v >= 0.5));
    // No window in flight: every weight is the absolute loss's.
    assert_eq!(relative_weights(&[2.0, 3.0], 1.0), Some(vec![1.0, 1.0]));
}

//! libtorch links and loads from the project-local venv (rpath from build.rs, no
//! LD_LIBRARY_PATH): a small tensor computation through tch.

#[test]
fn libtorch_computes() {
    let a = tch::Tensor::from_slice(&[1.0f32, 2.0, 3.0]);
    let b = (&a * &a).sum(tch::Kind::Float);
    assert_eq!(f32::try_from(b).unwrap(), 14.0);
}

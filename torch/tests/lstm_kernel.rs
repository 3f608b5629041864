//! The hand-written batched forward (`dronewatt::model::lstm_cpu`) equals libtorch's
//! `nn.LSTM` on random networks, at every batch size and on every instruction set this CPU
//! has, read from the same `.safetensors` file `dronewatt` reads.

use dronewatt::model::lstm_cpu::{CpuLstm, Isa};
use dronewatt_torch::Net;
use tch::nn::VarStore;
use tch::{Device, Kind, Tensor};

/// A randomly initialised network (non-zero biases, so their sum is exercised) saved to a
/// `.safetensors` file, its libtorch outputs for `windows` random windows of T = 10, and
/// those windows' inputs.
fn random_net(
    seed: i64,
    hidden: i64,
    layers: i64,
    windows: i64,
) -> (tempfile::TempDir, std::path::PathBuf, Vec<f32>, Vec<f32>) {
    random_net_reading(seed, hidden, layers, windows, None)
}

/// [`random_net`] whose head reads the top layer's states at window step `readout`.
fn random_net_reading(
    seed: i64,
    hidden: i64,
    layers: i64,
    windows: i64,
    readout: Option<usize>,
) -> (tempfile::TempDir, std::path::PathBuf, Vec<f32>, Vec<f32>) {
    tch::manual_seed(seed);
    let mut vs = VarStore::new(Device::Cpu);
    let net = Net::new(&vs.root(), hidden, layers, 0.2, readout);
    tch::no_grad(|| {
        for (name, mut v) in vs.variables() {
            if name.contains("bias") {
                let _ = v.uniform_(-0.3, 0.3);
            }
        }
    });
    vs.freeze();
    let x = Tensor::randn([windows, 10, 21], (Kind::Float, Device::Cpu)) * 1.5;
    let want = Vec::<f32>::try_from(tch::no_grad(|| net.forward_t(&x, false)).view([-1]))
        .expect("libtorch output");
    let xs = Vec::<f32>::try_from(x.view([-1])).expect("input");
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("net.safetensors");
    vs.save(&path).expect("save weights");
    (dir, path, want, xs)
}

/// Run the first `b` windows as one batch and compare every output with libtorch's.
fn check_batch(m: &mut CpuLstm, xs: &[f32], want: &[f32], b: usize, what: &str) {
    let (per, o) = (10 * 21, 3);
    let mut out = vec![f32::NAN; b * o];
    m.forward_batch(&xs[..b * per], 10, &mut out);
    for (i, (got, exp)) in out.iter().zip(&want[..b * o]).enumerate() {
        assert!(
            (got - exp).abs() < 1e-5,
            "{what}, batch {b}: window {} output {}: {got} vs libtorch {exp}",
            i / o,
            i % o
        );
    }
}

/// The paper's network (2 layers, 128 hidden) equals libtorch at every batch size from 1
/// to 67 (full 6-row tiles and every remainder, one and several row chunks), and at 131
/// (more than one pass of the kernel's chunk), on every instruction set this CPU has.
#[test]
fn matches_libtorch_at_every_batch_size() {
    let (_dir, path, want, xs) = random_net(3, 128, 2, 131);
    for isa in Isa::available() {
        let mut m = CpuLstm::from_safetensors(&path, 2, 128).expect("weights");
        m.set_isa(isa);
        assert_eq!(m.isa(), isa);
        let what = format!("{isa:?}");
        for b in (1..=67).chain([131]) {
            check_batch(&mut m, &xs, &want, b, &what);
        }
        // The single-window entry point is the same forward.
        let mut out = [0.0f32; 3];
        m.forward(&xs[5 * 210..6 * 210], 10, &mut out);
        let mut six = vec![0.0f32; 18];
        m.forward_batch(&xs[..6 * 210], 10, &mut six);
        assert_eq!(out.to_vec(), six[15..18].to_vec());
    }
}

/// Another shape: three layers of 24 hidden (4H = 96: six column blocks, so the few-row
/// tiles end on a lone block).
#[test]
fn matches_libtorch_on_another_shape() {
    let (_dir, path, want, xs) = random_net(11, 24, 3, 40);
    for isa in Isa::available() {
        let mut m = CpuLstm::from_safetensors(&path, 3, 24).expect("weights");
        m.set_isa(isa);
        let what = format!("{isa:?}");
        for b in [1, 2, 3, 4, 5, 6, 7, 8, 9, 13, 40] {
            check_batch(&mut m, &xs, &want, b, &what);
        }
    }
}

/// The instant readout (both directions' top-layer states at one step, each direction
/// stopping there) equals libtorch's `output[:, step]`, at every step of the window, the
/// first and the last included, on every instruction set; and it is not the final readout.
#[test]
fn instant_readout_matches_libtorch_at_every_step() {
    for step in 0..10 {
        let (_dir, path, want, xs) = random_net_reading(7, 32, 2, 9, Some(step));
        let (_d2, _p2, final_out, _) = random_net_reading(7, 32, 2, 9, None);
        assert!(
            want.iter()
                .zip(&final_out)
                .any(|(a, b)| (a - b).abs() > 1e-3),
            "step {step}: the instant readout should differ from the final one"
        );
        for isa in Isa::available() {
            let mut m = CpuLstm::from_safetensors(&path, 2, 32).expect("weights");
            m.set_isa(isa);
            m.set_readout(Some(step));
            let what = format!("{isa:?}, readout step {step}");
            for b in [1, 2, 7, 9] {
                check_batch(&mut m, &xs, &want, b, &what);
            }
        }
    }
}

/// Weights of another shape than the card says are refused with the file named, not run.
#[test]
fn wrong_shape_is_an_error() {
    let (_dir, path, _, _) = random_net(5, 24, 2, 1);
    let err = CpuLstm::from_safetensors(&path, 2, 32)
        .err()
        .expect("24 cells read as 32 must fail");
    assert!(format!("{err:#}").contains("net.safetensors"), "{err:#}");
    let err = CpuLstm::from_safetensors(&path, 3, 24)
        .err()
        .expect("2 layers read as 3 must fail");
    assert!(format!("{err:#}").contains("3-layer"), "{err:#}");
}

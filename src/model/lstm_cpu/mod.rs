//! A hand-written f32 forward pass of the shipped LSTM on the CPU, for any number of
//! windows at once: no allocation after warm-up, no libtorch dispatch.
//!
//! The network (see [`super::lstm`]) costs, for T steps, input width `I`, hidden `H` and
//! gates `G = 4H`, per window and direction: `T·I·G` multiply-adds for the input
//! projections and `T·H·G` for the recurrence. The paper's network (T = 10, I = 21 then
//! 2H = 256, H = 128, two layers, two directions) is 5.5 M multiply-adds a window; one
//! core's AVX2 FMA peak (2 × 8 lanes × 2 flops a cycle, ~96 GFLOP/s here) puts the floor at
//! ~113 µs a window.
//!
//! A batch of B windows is one sequence of small matrix products:
//!
//! - input projections of every step of every window at once: `pre = b + X W_ihᵀ`,
//!   X `[B·T][I]` (row `w·T + s` is window w's step s), `pre` `[B·T][G]`;
//! - then step by step the recurrent product of the whole batch, `pre_s += H W_hhᵀ`
//!   (H `[B][H]`, the rows of `pre` for step s at a stride of T rows), and the cell
//!   `c ← σ(f)c + σ(i)tanh(g)`, `h ← σ(o)tanh(c)` (gate order i, f, g, o as `nn.LSTM`;
//!   zero initial state; the backward direction walks s = T−1 … 0);
//! - the top layer keeps only its final forward and backward states, `[B][2H]`, for the
//!   dense head, `tanh(W_head h + b_head)` (or, with an instant readout, both directions'
//!   states at one step, each direction stopping there and projecting only the steps it
//!   walks: [`CpuLstm::set_readout`]).
//!
//! Each product runs through one GEMM (`gemm`): weights packed once into column blocks of
//! 16 gate outputs (`pack`, `[k][16]` contiguous: two AVX registers, one AVX-512 register),
//! and a register tile of accumulators that each weight load feeds several rows of:
//!
//! - AVX2 + FMA: 6 rows × 1 block (12 accumulators, the classic Haswell/Zen micro-kernel:
//!   12 FMAs for 2 weight loads and 6 broadcasts per input);
//! - AVX-512: 8 rows × 2 blocks (16 of the 32 registers; 16 FMAs of 16 lanes for 2 weight
//!   loads and 8 broadcasts), twice the arithmetic a cycle where the core has 512-bit FMA
//!   units (Zen 5, recent Xeons; measured here in `benches/lstm_cpu.rs`, and against libtorch in `torch/benches/lstm.rs`).
//!
//! Rows are taken in chunks of `MC` so the chunk's inputs stay in L2 while every weight
//! block passes over them. Fewer rows than a tile left (the live case of one window is 1
//! row in the recurrence) use a tile over several column blocks instead, keeping eight or
//! more independent accumulator chains for the two FMA pipes. Windows go through the
//! network `CHUNK_WINDOWS` at a time, which bounds the scratch space.
//!
//! Same maths as `nn.LSTM`, checked against libtorch to 1e-5 in the tests (every batch
//! size 1..=67, every instruction set the CPU has). The instruction set is detected at
//! run time ([`Isa`]): AVX-512F, else AVX2 + FMA, else (any other CPU) a plain scalar path
//! with the same results to rounding.

/// Gate outputs per packed weight block: two AVX registers.
const NR: usize = 16;
/// Rows of the register tile.
const MR: usize = 6;
/// Rows per GEMM pass: the chunk of inputs (≤ 96 × 256 × 4 B = 96 KiB) stays in L2 while
/// every weight block streams over it. A multiple of [`MR`].
const MC: usize = 96;
/// Windows per pass through the whole network: bounds the scratch space (the gate
/// pre-activations are `CHUNK_WINDOWS · T · 4H` floats, 2.5 MiB for the paper's network).
const CHUNK_WINDOWS: usize = 128;
/// From this many windows, the top layer's input projections with an instant readout run
/// one product a step over every window instead of one a window (a full AVX-512 tile).
const BY_STEP_WINDOWS: usize = 8;

/// One direction of one LSTM layer.
struct Direction {
    /// Inputs (`W_ih`'s columns).
    input: usize,
    /// `W_ih`, packed (see [`pack`]).
    w_ih: Vec<f32>,
    /// `W_hh`, packed.
    w_hh: Vec<f32>,
    /// `b_ih + b_hh`, `[4H]`.
    bias: Vec<f32>,
}

/// The weights of a stacked bidirectional LSTM with a dense head, laid out for batched
/// inference, and the scratch space it runs in.
pub struct CpuLstm {
    hidden: usize,
    layers: Vec<[Direction; 2]>,
    /// `[outputs][2H]`.
    head_w: Vec<f32>,
    head_b: Vec<f32>,
    isa: Isa,
    /// The window step whose top-layer states the head reads (`None`: the final ones; see
    /// [`crate::model::card::Readout`]).
    readout: Option<usize>,
    // Scratch, sized for up to CHUNK_WINDOWS windows: gate pre-activations [B·T][4H];
    // the next layer's input [B·T][2H]; states h and c [B][H]; the top layer's final
    // states [B][2H].
    pre: Vec<f32>,
    seq: Vec<f32>,
    h: Vec<f32>,
    c: Vec<f32>,
    last: Vec<f32>,
}

/// Pack `w` (`[n][k]`, PyTorch's layout, `n` a multiple of [`NR`]) into blocks of `NR`
/// outputs, each `[k][NR]` contiguous, so a product reads every block front to back.
fn pack(w: &[f32], n: usize, k: usize) -> Vec<f32> {
    let mut p = vec![0.0; n * k];
    for b in 0..n / NR {
        for kk in 0..k {
            for j in 0..NR {
                p[(b * k + kk) * NR + j] = w[(b * NR + j) * k + kk];
            }
        }
    }
    p
}

impl CpuLstm {
    /// Read the weights of the network from a `.safetensors` file (PyTorch's `nn.LSTM`
    /// and `nn.Linear` names under `lstm.` and `head.`, float32 or float64).
    pub fn from_safetensors(
        path: &std::path::Path,
        layers: usize,
        hidden: usize,
    ) -> anyhow::Result<CpuLstm> {
        use anyhow::Context;
        use safetensors::{Dtype, SafeTensors};
        let bytes = std::fs::read(path)
            .with_context(|| format!("{}: cannot read LSTM weights", path.display()))?;
        let st = SafeTensors::deserialize(&bytes)
            .with_context(|| format!("{}: not a safetensors file", path.display()))?;
        let get = |name: &str| -> Option<(Vec<f32>, Vec<usize>)> {
            let t = st.tensor(name).ok()?;
            let data = t.data();
            let values: Vec<f32> = match t.dtype() {
                Dtype::F32 => data
                    .chunks_exact(4)
                    .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                    .collect(),
                Dtype::F64 => data
                    .chunks_exact(8)
                    .map(|b| {
                        f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]) as f32
                    })
                    .collect(),
                _ => return None,
            };
            Some((values, t.shape().to_vec()))
        };
        CpuLstm::from_tensors(get, layers, hidden).with_context(|| {
            format!("{}: weights do not fit a {layers}-layer bidirectional LSTM of {hidden} cells with a dense head (a tensor is missing, of another type or shape)", path.display())
        })
    }

    /// Build from named tensors (`get(name)` → values, row-major, and shape), PyTorch's
    /// names (`lstm.weight_ih_l0_reverse`, `head.bias`, …). `None` when a tensor is missing
    /// or has an unexpected shape, or 4H is not a multiple of 16.
    pub fn from_tensors(
        get: impl Fn(&str) -> Option<(Vec<f32>, Vec<usize>)>,
        layers: usize,
        hidden: usize,
    ) -> Option<CpuLstm> {
        let g = 4 * hidden;
        let mut ls = Vec::new();
        for l in 0..layers {
            let dir = |suffix: &str| -> Option<Direction> {
                let (w_ih, s_ih) = get(&format!("lstm.weight_ih_l{l}{suffix}"))?;
                let (w_hh, s_hh) = get(&format!("lstm.weight_hh_l{l}{suffix}"))?;
                let (b_ih, _) = get(&format!("lstm.bias_ih_l{l}{suffix}"))?;
                let (b_hh, _) = get(&format!("lstm.bias_hh_l{l}{suffix}"))?;
                let input = *s_ih.get(1)?;
                let ok = g.is_multiple_of(NR)
                    && s_ih[0] == g
                    && s_hh == [g, hidden]
                    && w_hh.len() == g * hidden
                    && w_ih.len() == g * input
                    && b_ih.len() == g
                    && b_hh.len() == g;
                ok.then(|| Direction {
                    input,
                    w_ih: pack(&w_ih, g, input),
                    w_hh: pack(&w_hh, g, hidden),
                    bias: b_ih.iter().zip(&b_hh).map(|(a, b)| a + b).collect(),
                })
            };
            ls.push([dir("")?, dir("_reverse")?]);
        }
        let (head_w, hs) = get("head.weight")?;
        let (head_b, _) = get("head.bias")?;
        if hs.get(1).copied()? != 2 * hidden
            || head_b.len() != hs[0]
            || head_w.len() != hs[0] * 2 * hidden
        {
            return None;
        }
        Some(CpuLstm {
            hidden,
            layers: ls,
            head_w,
            head_b,
            isa: Isa::detect(),
            readout: None,
            pre: Vec::new(),
            seq: Vec::new(),
            h: Vec::new(),
            c: Vec::new(),
            last: Vec::new(),
        })
    }

    /// The instruction set the forward runs on.
    pub fn isa(&self) -> Isa {
        self.isa
    }

    /// Run on `isa` instead of the best detected (tests compare every path; an
    /// instruction set the CPU lacks is ignored).
    pub fn set_isa(&mut self, isa: Isa) {
        if Isa::available().contains(&isa) {
            self.isa = isa;
        }
    }

    /// Read the top layer's states at window step `step` (both directions) instead of the
    /// final ones (`None`). The forward direction then stops at `step`, the backward one
    /// walks from the newest sample back to it. A step beyond a window reads its final
    /// forward state and its newest backward one.
    pub fn set_readout(&mut self, step: Option<usize>) {
        self.readout = step;
    }

    /// Inputs per step (the first layer's width).
    pub fn inputs(&self) -> usize {
        self.layers[0][0].input
    }

    /// Outputs of the dense head.
    pub fn outputs(&self) -> usize {
        self.head_b.len()
    }

    /// Forward one standardised window `x` (`[T][inputs]`, row-major) into `out` (`tanh`
    /// of the dense head, [`Self::outputs`] values).
    pub fn forward(&mut self, x: &[f32], t: usize, out: &mut [f32]) {
        self.forward_batch(x, t, out);
    }

    /// Forward a batch of standardised windows `xs` (`[B][T][inputs]`, row-major; B is
    /// `xs.len() / (T · inputs)`) into `out` (`[B][outputs]`).
    pub fn forward_batch(&mut self, xs: &[f32], t: usize, out: &mut [f32]) {
        let per_window = t * self.inputs();
        assert!(
            per_window > 0 && xs.len().is_multiple_of(per_window),
            "windows of the wrong size"
        );
        let b = xs.len() / per_window;
        let o = self.outputs();
        assert_eq!(out.len(), b * o, "output of the wrong size");
        for (xc, oc) in xs
            .chunks(CHUNK_WINDOWS * per_window)
            .zip(out.chunks_mut(CHUNK_WINDOWS * o))
        {
            self.forward_chunk(xc, t, xc.len() / per_window, oc);
        }
    }

    /// [`Self::forward_batch`] for at most [`CHUNK_WINDOWS`] windows.
    fn forward_chunk(&mut self, xs: &[f32], t: usize, b: usize, out: &mut [f32]) {
        let (hd, g) = (self.hidden, 4 * self.hidden);
        let n_layers = self.layers.len();
        let isa = self.isa;
        self.pre.resize(b * t * g, 0.0);
        self.h.resize(b * hd, 0.0);
        self.c.resize(b * hd, 0.0);
        self.last.resize(b * 2 * hd, 0.0);
        // The layer below's output; layer 0 reads the windows themselves.
        let mut below = std::mem::take(&mut self.seq);
        let mut next = Vec::new();
        for l in 0..n_layers {
            let top = l + 1 == n_layers;
            next.clear();
            if !top {
                next.resize(b * t * 2 * hd, 0.0);
            }
            let input: &[f32] = if l == 0 { xs } else { &below };
            for (d, dir) in self.layers[l].iter().enumerate() {
                // The top layer stops where the head reads it: the forward direction at
                // the readout step, the backward one back at it (t − r steps). Only the
                // steps it walks, `first..first + steps` of each window, need projections.
                let (first, steps) = match (top, self.readout) {
                    (true, Some(r)) if d == 0 => (0, r.min(t - 1) + 1),
                    (true, Some(r)) => (r.min(t - 1), t - r.min(t - 1)),
                    _ => (0, t),
                };
                // Input projections of those steps of every window: pre = bias + X W_ihᵀ,
                // all windows in one product when every step is walked; else, for a batch
                // of at least a tile of windows, one product a step over every window (its
                // rows T apart, so the weights feed whole tiles of windows), and for fewer
                // one product a window. Each output is the same sum in the same order
                // whichever way.
                let whole = steps == t;
                let by_step = !whole && b >= BY_STEP_WINDOWS;
                for w in 0..b {
                    let at = w * t + first;
                    for row in self.pre[at * g..(at + steps) * g].chunks_exact_mut(g) {
                        row.copy_from_slice(&dir.bias);
                    }
                }
                let products = match (whole, by_step) {
                    (true, _) => 1,
                    (false, true) => steps,
                    (false, false) => b,
                };
                for p in 0..products {
                    let (at, rows, ld) = match (whole, by_step) {
                        (true, _) => (0, b * t, 1),
                        (false, true) => (first + p, b, t),
                        (false, false) => (p * t + first, steps, 1),
                    };
                    gemm(
                        isa,
                        &dir.w_ih,
                        dir.input,
                        &input[at * dir.input..],
                        ld * dir.input,
                        rows,
                        &mut self.pre[at * g..],
                        ld * g,
                    );
                }
                self.h.iter_mut().for_each(|v| *v = 0.0);
                self.c.iter_mut().for_each(|v| *v = 0.0);
                for k in 0..steps {
                    let s = if d == 0 { k } else { t - 1 - k };
                    // pre_s += H W_hhᵀ: the rows of step s are T rows apart.
                    gemm(
                        isa,
                        &dir.w_hh,
                        hd,
                        &self.h,
                        hd,
                        b,
                        &mut self.pre[s * g..],
                        t * g,
                    );
                    for w in 0..b {
                        let gates = &self.pre[(w * t + s) * g..(w * t + s + 1) * g];
                        let (c, h) = (
                            &mut self.c[w * hd..(w + 1) * hd],
                            &mut self.h[w * hd..(w + 1) * hd],
                        );
                        cell(isa, gates, c, h);
                        if !top {
                            let at = (w * t + s) * 2 * hd + d * hd;
                            next[at..at + hd].copy_from_slice(h);
                        }
                    }
                }
                if top {
                    for w in 0..b {
                        self.last[w * 2 * hd + d * hd..w * 2 * hd + (d + 1) * hd]
                            .copy_from_slice(&self.h[w * hd..(w + 1) * hd]);
                    }
                }
            }
            std::mem::swap(&mut below, &mut next);
        }
        self.seq = below;
        let o = self.outputs();
        for w in 0..b {
            let last = &self.last[w * 2 * hd..(w + 1) * 2 * hd];
            for (j, v) in out[w * o..(w + 1) * o].iter_mut().enumerate() {
                let hw = &self.head_w[j * 2 * hd..(j + 1) * 2 * hd];
                let z: f32 = self.head_b[j] + hw.iter().zip(last).map(|(a, b)| a * b).sum::<f32>();
                *v = z.tanh();
            }
        }
    }
}

/// The instruction set the kernel runs on, best first.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Isa {
    /// Plain Rust, any CPU.
    Scalar,
    /// x86-64 AVX2 + FMA: 8 lanes.
    Avx2,
    /// x86-64 AVX-512F (with AVX2 + FMA for the cell): 16 lanes.
    Avx512,
}

impl Isa {
    /// The best this CPU has.
    pub fn detect() -> Isa {
        Isa::available().into_iter().max().unwrap_or(Isa::Scalar)
    }

    /// Every instruction set this CPU runs (the tests try each).
    pub fn available() -> Vec<Isa> {
        let mut v = vec![Isa::Scalar];
        #[cfg(target_arch = "x86_64")]
        if is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma") {
            v.push(Isa::Avx2);
            if is_x86_feature_detected!("avx512f") {
                v.push(Isa::Avx512);
            }
        }
        v
    }
}

/// `y[r] += W x[r]` for rows `r < rows`: `w` packed `[n][k]` (see [`pack`]), row r of x at
/// `x[r·ldx ..][..k]`, of y at `y[r·ldy ..][..n]` (`n = w.len() / k`).
#[allow(clippy::too_many_arguments)] // a BLAS-shaped call: the names are the contract
fn gemm(
    isa: Isa,
    w: &[f32],
    k: usize,
    x: &[f32],
    ldx: usize,
    rows: usize,
    y: &mut [f32],
    ldy: usize,
) {
    let n = w.len() / k;
    assert!(
        rows > 0
            && n.is_multiple_of(NR)
            && w.len() == n * k
            && ldx >= k
            && ldy >= n
            && x.len() >= (rows - 1) * ldx + k
            && y.len() >= (rows - 1) * ldy + n
    );
    #[cfg(target_arch = "x86_64")]
    match isa {
        // SAFETY: the instruction sets were detected at run time (`Isa::available`); the
        // sizes are checked above.
        Isa::Avx512 => {
            return unsafe {
                avx512::gemm(w.as_ptr(), k, n, x.as_ptr(), ldx, rows, y.as_mut_ptr(), ldy)
            }
        }
        Isa::Avx2 => {
            return unsafe {
                avx::gemm(w.as_ptr(), k, n, x.as_ptr(), ldx, rows, y.as_mut_ptr(), ldy)
            }
        }
        Isa::Scalar => {}
    }
    let _ = isa;
    for (b, wb) in w.chunks_exact(k * NR).enumerate() {
        for r in 0..rows {
            let yr = &mut y[r * ldy + b * NR..r * ldy + (b + 1) * NR];
            for (kk, wk) in wb.chunks_exact(NR).enumerate() {
                let xv = x[r * ldx + kk];
                for (yj, wj) in yr.iter_mut().zip(wk) {
                    *yj += xv * wj;
                }
            }
        }
    }
}

/// The LSTM cell on pre-activations `gates` = [i, f, g, o] (each H): c ← σ(f)c + σ(i)tanh(g),
/// h ← σ(o) tanh(c).
fn cell(isa: Isa, gates: &[f32], c: &mut [f32], h: &mut [f32]) {
    let hd = h.len();
    #[cfg(target_arch = "x86_64")]
    if isa == Isa::Avx512 && hd.is_multiple_of(16) {
        // SAFETY: AVX-512F was detected at run time.
        unsafe { avx512::cell(gates, c, h) };
        return;
    }
    #[cfg(target_arch = "x86_64")]
    if isa >= Isa::Avx2 && hd.is_multiple_of(8) {
        // SAFETY: AVX2 and FMA were detected at run time (every Isa above Avx2 has them).
        unsafe { avx::cell(gates, c, h) };
        return;
    }
    let _ = isa;
    let sig = |v: f32| 1.0 / (1.0 + (-v).exp());
    for j in 0..hd {
        let (i, f, g, o) = (
            sig(gates[j]),
            sig(gates[hd + j]),
            gates[2 * hd + j].tanh(),
            sig(gates[3 * hd + j]),
        );
        c[j] = f * c[j] + i * g;
        h[j] = o * c[j].tanh();
    }
}

#[cfg(target_arch = "x86_64")]
#[macro_use]
mod x86;

#[cfg(target_arch = "x86_64")]
mod avx;

#[cfg(target_arch = "x86_64")]
mod avx512;

#[cfg(test)]
mod tests;

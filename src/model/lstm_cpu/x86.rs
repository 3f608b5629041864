//! What the x86-64 kernels share: the batched matrix product's driver and register tile,
//! written once for a vector width ([`super::avx`]: 8 lanes, [`super::avx512`]: 16).

/// `gemm`, `blocks` and `tile` of one instruction set: `$feature` its `#[target_feature]`,
/// `$lanes` floats a register (the `$zero`, `$load`, `$store`, `$set1`, `$fma`
/// intrinsics), full tiles of `$mr` rows × `$mb` blocks, and for each remainder of fewer
/// rows the blocks its tile spans (`$rest => $b`; the `else` one for the largest).
macro_rules! gemm_kernel {
    (
        feature: $feature:literal,
        lanes: $lanes:literal,
        ops: $zero:ident, $load:ident, $store:ident, $set1:ident, $fma:ident,
        full: $mr:expr => $mb:literal,
        rest: $($rest:literal => $b:literal),+, else $lr:literal => $lb:literal $(,)?
    ) => {
        /// `y[r] += W x[r]` (see `super::gemm`; sizes checked there). Rows in chunks of
        /// `MC`; in each, the chunk's full tiles, then the rows left over (fewer than a
        /// tile) over several blocks at a time.
        #[allow(clippy::too_many_arguments)]
        #[target_feature(enable = $feature)]
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
                let full = mc / $mr * $mr;
                if full > 0 {
                    let (xr, yr) = (x.add(r0 * ldx), y.add(r0 * ldy));
                    blocks::<{ $mr }, $mb>(w, step, nb, k, full, xr, ldx, yr, ldy);
                }
                let (r, rest) = (r0 + full, mc - full);
                let (xr, yr) = (x.add(r * ldx), y.add(r * ldy));
                match rest {
                    0 => {}
                    $($rest => blocks::<$rest, $b>(w, step, nb, k, $rest, xr, ldx, yr, ldy),)+
                    _ => blocks::<$lr, $lb>(w, step, nb, k, $lr, xr, ldx, yr, ldy),
                }
                r0 += mc;
            }
        }

        /// `rows` rows (a multiple of `R`) over every column block, `B` blocks a tile (one
        /// block a tile at the end); each group of blocks passes over all the rows while
        /// its weights stay in L1.
        #[allow(clippy::too_many_arguments)]
        #[inline]
        #[target_feature(enable = $feature)]
        unsafe fn blocks<const R: usize, const B: usize>(
            w: *const f32,
            step: usize,
            nb: usize,
            k: usize,
            rows: usize,
            x: *const f32,
            ldx: usize,
            y: *mut f32,
            ldy: usize,
        ) {
            let mut b = 0;
            while b < nb {
                let wide = b + B <= nb;
                let mut r = 0;
                while r < rows {
                    let (xr, yr) = (x.add(r * ldx), y.add(r * ldy + b * NR));
                    if wide {
                        tile::<R, B>(w.add(b * step), step, k, xr, ldx, yr, ldy);
                    } else {
                        tile::<R, 1>(w.add(b * step), step, k, xr, ldx, yr, ldy);
                    }
                    r += R;
                }
                b += if wide { B } else { 1 };
            }
        }

        /// The register tile: `R` rows × `B` packed blocks of 16 outputs (`Q` registers a
        /// block), `R·B·Q` accumulators loaded from y, `k` rank-1 updates, stored back.
        #[allow(clippy::too_many_arguments, clippy::needless_range_loop)] // acc[r][b][q]: registers, clearer indexed
        #[inline]
        #[target_feature(enable = $feature)]
        unsafe fn tile<const R: usize, const B: usize>(
            w: *const f32,
            step: usize,
            k: usize,
            x: *const f32,
            ldx: usize,
            y: *mut f32,
            ldy: usize,
        ) {
            const Q: usize = NR / $lanes;
            let mut acc = [[[$zero(); Q]; B]; R];
            for r in 0..R {
                for b in 0..B {
                    for q in 0..Q {
                        acc[r][b][q] = $load(y.add(r * ldy + b * NR + $lanes * q));
                    }
                }
            }
            for kk in 0..k {
                let mut wv = [[$zero(); Q]; B];
                for b in 0..B {
                    for q in 0..Q {
                        wv[b][q] = $load(w.add(b * step + kk * NR + $lanes * q));
                    }
                }
                for r in 0..R {
                    let xv = $set1(*x.add(r * ldx + kk));
                    for b in 0..B {
                        for q in 0..Q {
                            acc[r][b][q] = $fma(wv[b][q], xv, acc[r][b][q]);
                        }
                    }
                }
            }
            for r in 0..R {
                for b in 0..B {
                    for q in 0..Q {
                        $store(y.add(r * ldy + b * NR + $lanes * q), acc[r][b][q]);
                    }
                }
            }
        }
    };
}

//! The simulated weather and GNSS error: mean wind plus Gauss–Markov gusts, the autopilot's slow
//! wind estimate, and the GNSS position error.

use nalgebra::Vector3;
use rand::rngs::StdRng;

use super::{std_normal, SimOptions, DT};

/// Gauss–Markov (first-order) noise: `x ← x·e^{−dt/τ} + σ·√(1−e^{−2dt/τ})·N(0,1)`.
#[derive(Debug, Clone, Copy)]
struct Markov {
    x: f64,
    sigma: f64,
    tau: f64,
}

impl Markov {
    fn step(&mut self, rng: &mut StdRng, dt: f64) -> f64 {
        let a = (-dt / self.tau).exp();
        self.x = self.x * a + self.sigma * (1.0 - a * a).sqrt() * std_normal(rng);
        self.x
    }
}

/// The weather and the GNSS error: mean wind plus Gauss–Markov gusts, the autopilot's slow
/// wind estimate, and the GNSS position error. One per flight, drawn from the flight's RNG.
pub(crate) struct Weather {
    mean: Vector3<f64>,
    gust: [Markov; 3],
    gps_err: [Markov; 3],
    /// The autopilot's wind estimate, NED m/s.
    pub wind_est: Vector3<f64>,
}

impl Weather {
    /// Gusts of σ = 0.1·wind + 0.2 m/s horizontally (30 % of it vertically), τ = 4 s; GNSS
    /// error σ 0.6/0.6/0.4 m, τ 20/20/10 s.
    pub fn new(opts: &SimOptions) -> Self {
        let mean = opts.wind_ned();
        let gust_sigma = 0.1 * opts.wind_mps + 0.2;
        let mut gust = [Markov {
            x: 0.0,
            sigma: gust_sigma,
            tau: 4.0,
        }; 3];
        gust[2].sigma = 0.3 * gust_sigma;
        let m = |sigma, tau| Markov { x: 0.0, sigma, tau };
        Self {
            mean,
            gust,
            gps_err: [m(0.6, 20.0), m(0.6, 20.0), m(0.4, 10.0)],
            wind_est: mean,
        }
    }

    /// The wind this step (mean + gust), and the estimate's filter (τ = 3 s) stepped.
    pub fn wind(&mut self, rng: &mut StdRng) -> Vector3<f64> {
        let g = Vector3::new(
            self.gust[0].step(rng, DT),
            self.gust[1].step(rng, DT),
            self.gust[2].step(rng, DT),
        );
        let w = self.mean + g;
        self.wind_est += (w - self.wind_est) * (DT / 3.0);
        w
    }

    /// The GNSS position error this step, NED m.
    pub fn gps(&mut self, rng: &mut StdRng) -> Vector3<f64> {
        Vector3::new(
            self.gps_err[0].step(rng, DT),
            self.gps_err[1].step(rng, DT),
            self.gps_err[2].step(rng, DT),
        )
    }
}

//! Latency of the live path after a message arrives, per 10 Hz tick: telemetry (state,
//! resampling, window) → every model the default configuration builds → energy → alert
//! rules (the example config's nine) → MAVLink encoding of the estimates and alerts.
//!
//! `cargo bench --bench latency` prints, before criterion's own figures, the p50/p99/max of
//! 20 000 timed ticks of that whole chain (criterion reports means and medians, not a p99).
//! The tokio channel hops between the stages are not in it (a few µs each); the end-to-end
//! figure over a real UDP link is `scripts/bench-live.sh`.

use std::hint::black_box;
use std::time::Instant;

use criterion::Criterion;
use dronewatt::config::Config;
use dronewatt::dialect as d;
use dronewatt::pipeline::{account, VehicleChain};
use dronewatt::report::Report;
use dronewatt::sink::mavlink::Encoder;
use dronewatt::source::TimedMessage;
use dronewatt::MavMessage;

/// The messages one 10 Hz tick of an ArduPilot-like stream carries, at time `t_s`.
fn tick(t_s: f64) -> Vec<TimedMessage> {
    let ms = (t_s * 1000.0) as u32;
    let north = t_s * 10.0;
    let msgs = vec![
        MavMessage::SYS_STATUS(d::SYS_STATUS_DATA {
            voltage_battery: 22_200,
            current_battery: (2250.0 + 180.0 * (t_s / 3.0).sin()) as i16,
            battery_remaining: -1,
            ..Default::default()
        }),
        MavMessage::GLOBAL_POSITION_INT(d::GLOBAL_POSITION_INT_DATA {
            time_boot_ms: ms,
            lat: 473_977_419 + (north / 111_320.0 * 1e7) as i32,
            lon: 85_455_938,
            alt: 425_000,
            relative_alt: 25_000,
            vx: 1000,
            ..Default::default()
        }),
        MavMessage::ATTITUDE(d::ATTITUDE_DATA {
            time_boot_ms: ms,
            pitch: -0.1,
            ..Default::default()
        }),
        MavMessage::VFR_HUD(d::VFR_HUD_DATA {
            airspeed: 10.0,
            groundspeed: 10.0,
            alt: 25.0,
            ..Default::default()
        }),
        MavMessage::HIGHRES_IMU(d::HIGHRES_IMU_DATA {
            time_usec: u64::from(ms) * 1000,
            zacc: -9.81,
            ..Default::default()
        }),
        MavMessage::WIND(d::WIND_DATA {
            direction: 180.0,
            speed: 2.0,
            speed_z: 0.0,
        }),
        MavMessage::HOME_POSITION(d::HOME_POSITION_DATA {
            latitude: 473_977_419,
            longitude: 85_455_938,
            ..Default::default()
        }),
    ];
    msgs.into_iter()
        .map(|msg| {
            let header = mavlink::MavHeader {
                system_id: 1,
                component_id: 1,
                sequence: 0,
            };
            TimedMessage::new(t_s, header, msg)
        })
        .collect()
}

struct Chain {
    chain: VehicleChain,
    enc: Encoder,
    reports: Vec<Report>,
}

impl Chain {
    fn new() -> Chain {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("config/dronewatt.toml");
        let cfg = Config::load(&path).unwrap_or_else(|e| panic!("{e}"));
        Chain {
            chain: dronewatt::pipeline::Resolved::load(&cfg)
                .and_then(|r| VehicleChain::build(&cfg, &r))
                .unwrap_or_else(|e| panic!("{e:#}")),
            enc: Encoder::new(1, 191),
            reports: Vec::new(),
        }
    }

    /// One tick's messages through every stage; returns the frames a MAVLink sink would send.
    fn run(&mut self, msgs: &[TimedMessage]) -> usize {
        let mut frames = 0;
        for m in msgs {
            self.chain.push(Some(m), &mut self.reports);
        }
        for r in self.reports.drain(..) {
            frames += self.enc.estimates(&r).len() + self.enc.alerts(&r).len();
        }
        frames
    }
}

fn percentiles() {
    let mut chain = Chain::new();
    let ticks: Vec<Vec<TimedMessage>> = (0..22_000).map(|i| tick(i as f64 * 0.1)).collect();
    // Warm up: fill the window, let the forecasts settle.
    for t in &ticks[..2000] {
        chain.run(t);
    }
    let mut ns = Vec::with_capacity(20_000);
    let mut frames = 0;
    for t in &ticks[2000..] {
        let t0 = Instant::now();
        frames += black_box(chain.run(black_box(t)));
        ns.push(t0.elapsed().as_nanos() as u64);
    }
    ns.sort_unstable();
    let q = |p: f64| ns[((ns.len() as f64 - 1.0) * p) as usize] as f64 / 1000.0;
    println!(
        "live chain per 10 Hz tick (models: {:?}): p50 {:.1} µs, p99 {:.1} µs, max {:.1} µs over {} ticks, {} frames encoded",
        chain.chain.models.names(),
        q(0.5),
        q(0.99),
        q(1.0),
        ns.len(),
        frames
    );
}

fn main() {
    percentiles();
    let mut c = Criterion::default().configure_from_args();
    let mut chain = Chain::new();
    let mut i = 0u64;
    let ticks: Vec<Vec<TimedMessage>> = (0..200).map(|i| tick(i as f64 * 0.1)).collect();
    for t in &ticks[..100] {
        chain.run(t);
    }
    c.bench_function("live_chain_tick", |b| {
        b.iter(|| {
            i += 1;
            let t = tick(10.0 + i as f64 * 0.1);
            black_box(chain.run(black_box(&t)))
        })
    });
    // The energy + alert + encode stage alone, on a fixed estimate.
    let mut chain = Chain::new();
    let est = dronewatt::report::Estimate {
        arrived: None,
        t_s: 0.0,
        sample: dronewatt::features::Sample {
            t_s: 0.0,
            features: [0.0; dronewatt::features::N_FEATURES],
            measured_w: Some(500.0),
            voltage_v: Some(22.2),
            home: Some(dronewatt::features::HomeVector {
                distance_m: 300.0,
                height_m: 25.0,
            }),
            stale_mask: 0,
            battery_remaining_pct: None,
            vehicle: Default::default(),
            air: Default::default(),
        },
        models: vec![],
    };
    let mut t = 0.0;
    c.bench_function("energy_alerts_encode", |b| {
        b.iter(|| {
            t += 0.1;
            let mut e = est.clone();
            e.t_s = t;
            let r = account(
                &mut chain.chain.energy,
                &mut chain.chain.alerts,
                e,
                dronewatt::report::VehicleId::single(1),
            );
            black_box(chain.enc.estimates(&r).len() + chain.enc.alerts(&r).len())
        })
    });
    c.final_summary();
}

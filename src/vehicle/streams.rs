//! Asking the vehicle for the streams the chain needs, as ground stations do.
//!
//! [`StreamAsker`] is a pure state machine beside [`super::params::ParamReader`]: messages and
//! their times in, requests out. [`OBSERVE_S`] after the vehicle's first HEARTBEAT it looks at
//! what arrived and, for each message the chain needs ([`wanted`]) that comes slower than it
//! needs, sends MAV_CMD_SET_MESSAGE_INTERVAL (one at a time; the COMMAND_ACK does not say
//! which message it answers). A request unanswered for [`super::params::RESEND_S`] is sent
//! again, [`super::params::MAX_TRIES`] times in all.
//!
//! - **Granted** (MAV_RESULT_ACCEPTED): said once all are answered ("vehicle granted ...").
//! - **Denied, unsupported, failed or never answered**: on ArduPilot the fallback is its
//!   REQUEST_DATA_STREAM for the streams holding those messages (said: "vehicle did not grant
//!   SET_MESSAGE_INTERVAL for ATTITUDE (MAV_RESULT_DENIED), ...: asked with
//!   REQUEST_DATA_STREAM"); elsewhere dronewatt
//!   says it listens at the vehicle's own rates.
//! - **What came of it**: [`SEEN_AFTER_S`] after the last answer, the rates seen of every
//!   message asked for, beside the rate asked ("rates seen: ATTITUDE 10.0 Hz (asked 10)").
//!
//! Nothing waits on it: the telemetry adapts to whatever rate arrives
//! ([`crate::telemetry::resample`]). `--listen-only` (`[link] listen_only`) never asks.

// MAVLink deprecates REQUEST_DATA_STREAM for SET_MESSAGE_INTERVAL; ArduPilot still obeys it,
// and it is the fallback on purpose.
#![allow(deprecated)]

use std::collections::BTreeMap;

use crate::dialect::{self, MavCmd, MavDataStream, MavResult};
use crate::source::TimedMessage;
use crate::MavMessage;

use super::params::{Autopilot, Identity, MAX_TRIES, RESEND_S};

/// Seconds of the vehicle's own rates watched before asking.
pub const OBSERVE_S: f64 = 3.0;
/// Seconds after the last answer over which the rates seen are measured and said.
pub const SEEN_AFTER_S: f64 = 5.0;
/// A message arriving at this share of the rate wanted or more is not asked for.
const ENOUGH: f64 = 0.8;

/// One message the chain needs: its name, MAVLink id, the rate wanted (Hz) and the
/// ArduPilot data stream that carries it (the fallback).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Want {
    pub name: &'static str,
    pub id: u32,
    pub hz: f64,
    pub stream: MavDataStream,
}

const fn want(name: &'static str, id: u32, hz: f64, stream: MavDataStream) -> Want {
    Want {
        name,
        id,
        hz,
        stream,
    }
}

use MavDataStream::{
    MAV_DATA_STREAM_EXTENDED_STATUS as EXT_STATUS, MAV_DATA_STREAM_EXTRA1 as EXTRA1,
    MAV_DATA_STREAM_EXTRA2 as EXTRA2, MAV_DATA_STREAM_EXTRA3 as EXTRA3,
    MAV_DATA_STREAM_POSITION as POSITION, MAV_DATA_STREAM_RAW_SENSORS as RAW_SENSORS,
};

/// ArduPilot's messages for every feature (and the streams ArduPilot sends them in).
const ARDUPILOT: [Want; 7] = [
    want("ATTITUDE", 30, 10.0, EXTRA1),
    want("RAW_IMU", 27, 10.0, RAW_SENSORS),
    want("GLOBAL_POSITION_INT", 33, 5.0, POSITION),
    want("VFR_HUD", 74, 4.0, EXTRA2),
    want("WIND", 168, 2.0, EXTRA3),
    want("SYS_STATUS", 1, 2.0, EXT_STATUS),
    want("BATTERY_STATUS", 147, 2.0, EXTRA3),
];
/// PX4's (no WIND; the attitude as a quaternion, the IMU in SI units).
const PX4: [Want; 7] = [
    want("ATTITUDE_QUATERNION", 31, 10.0, EXTRA1),
    want("HIGHRES_IMU", 105, 10.0, RAW_SENSORS),
    want("GLOBAL_POSITION_INT", 33, 5.0, POSITION),
    want("LOCAL_POSITION_NED", 32, 5.0, POSITION),
    want("VFR_HUD", 74, 4.0, EXTRA2),
    want("SYS_STATUS", 1, 2.0, EXT_STATUS),
    want("BATTERY_STATUS", 147, 2.0, EXTRA3),
];

/// The messages worth asking `autopilot` for, at the rates the chain wants them.
pub fn wanted(autopilot: Autopilot) -> &'static [Want] {
    match autopilot {
        Autopilot::Px4 => &PX4,
        Autopilot::ArduPilot | Autopilot::Other => &ARDUPILOT,
    }
}

/// How one ask ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Answer {
    Granted,
    /// Refused with this result (DENIED, UNSUPPORTED, FAILED, …).
    Refused(MavResult),
    /// Asked [`MAX_TRIES`] times, no COMMAND_ACK.
    Unanswered,
}

#[derive(Debug, Clone, Copy)]
enum Phase {
    /// Waiting for the vehicle, then watching its own rates until `until_s`.
    Observe {
        until_s: Option<f64>,
    },
    /// Asking `queue[next]`: sent `tries` times, last at `at_s`.
    Asking {
        next: usize,
        tries: u32,
        at_s: f64,
    },
    /// All answered; the rates seen are said at `say_at_s`.
    Settled {
        say_at_s: f64,
    },
    Done,
}

/// The stream requests as a state machine (module docs).
#[derive(Debug)]
pub struct StreamAsker {
    identity: Option<Identity>,
    phase: Phase,
    /// Message id → times heard (since the last count was started).
    heard: BTreeMap<u32, u32>,
    count_from_s: f64,
    queue: Vec<Want>,
    answers: Vec<(Want, Answer)>,
}

impl Default for StreamAsker {
    fn default() -> Self {
        Self::new()
    }
}

impl StreamAsker {
    pub fn new() -> Self {
        Self {
            identity: None,
            phase: Phase::Observe { until_s: None },
            heard: BTreeMap::new(),
            count_from_s: 0.0,
            queue: Vec::new(),
            answers: Vec::new(),
        }
    }

    /// The answers so far, in the order asked.
    pub fn answers(&self) -> &[(Want, Answer)] {
        &self.answers
    }

    /// Take one message from the vehicle (`identity`: the vehicle as the parameter reader
    /// knows it); the requests due at its time.
    pub fn on_message(&mut self, m: &TimedMessage, identity: Option<&Identity>) -> Vec<MavMessage> {
        let Some(id) = identity.filter(|id| id.system_id as u32 == m.header.system_id) else {
            return Vec::new();
        };
        if self.identity.is_none() {
            self.identity = Some(id.clone());
            self.count_from_s = m.t_s;
        }
        *self
            .heard
            .entry(mavlink::Message::message_id(&m.msg))
            .or_default() += 1;
        if let MavMessage::COMMAND_ACK(a) = &m.msg {
            if a.command == MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL {
                self.acked(m.t_s, a.result);
            }
        }
        self.poll(m.t_s)
    }

    fn acked(&mut self, t_s: f64, result: MavResult) {
        let Phase::Asking { next, .. } = self.phase else {
            return;
        };
        let answer = match result {
            MavResult::MAV_RESULT_ACCEPTED => Answer::Granted,
            MavResult::MAV_RESULT_IN_PROGRESS => return,
            r => Answer::Refused(r),
        };
        self.answers.push((self.queue[next], answer));
        self.phase = self.ask_next(next + 1, t_s);
    }

    fn ask_next(&mut self, next: usize, t_s: f64) -> Phase {
        if next < self.queue.len() {
            Phase::Asking {
                next,
                tries: 0,
                at_s: f64::NEG_INFINITY,
            }
        } else {
            self.heard.clear();
            self.count_from_s = t_s;
            Phase::Settled {
                say_at_s: t_s + SEEN_AFTER_S,
            }
        }
    }

    fn poll(&mut self, t_s: f64) -> Vec<MavMessage> {
        let Some(id) = self.identity.clone() else {
            return Vec::new();
        };
        match self.phase {
            Phase::Observe { until_s: None } => {
                self.phase = Phase::Observe {
                    until_s: Some(t_s + OBSERVE_S),
                };
                Vec::new()
            }
            Phase::Observe { until_s: Some(u) } if t_s >= u => {
                let span = (t_s - self.count_from_s).max(1e-3);
                self.queue = wanted(id.autopilot)
                    .iter()
                    .filter(|w| {
                        let hz = f64::from(self.heard.get(&w.id).copied().unwrap_or(0)) / span;
                        hz < ENOUGH * w.hz
                    })
                    .copied()
                    .collect();
                if self.queue.is_empty() {
                    tracing::info!(
                        "the vehicle already sends every stream at the rate the estimate needs"
                    );
                    self.phase = Phase::Done;
                    return Vec::new();
                }
                self.phase = self.ask_next(0, t_s);
                self.poll(t_s)
            }
            Phase::Asking { next, tries, at_s } if t_s - at_s >= RESEND_S => {
                if tries >= MAX_TRIES {
                    self.answers.push((self.queue[next], Answer::Unanswered));
                    self.phase = self.ask_next(next + 1, t_s);
                    return self.poll(t_s);
                }
                self.phase = Phase::Asking {
                    next,
                    tries: tries + 1,
                    at_s: t_s,
                };
                vec![set_interval(&id, &self.queue[next])]
            }
            Phase::Settled { say_at_s } if t_s >= say_at_s => {
                self.say_seen(t_s);
                self.phase = Phase::Done;
                Vec::new()
            }
            _ => {
                if matches!(self.phase, Phase::Settled { .. }) && self.fallback_due() {
                    return self.fallback(&id);
                }
                Vec::new()
            }
        }
    }

    /// Whether the answers are in and the fallback has not been sent yet.
    fn fallback_due(&mut self) -> bool {
        let due = !self.answers.is_empty() && !self.queue.is_empty();
        if due {
            self.say_answers();
        }
        self.queue.clear();
        due
    }

    fn say_answers(&self) {
        let granted: Vec<String> = self
            .answers
            .iter()
            .filter(|(_, a)| *a == Answer::Granted)
            .map(|(w, _)| format!("{} {} Hz", w.name, w.hz))
            .collect();
        if !granted.is_empty() {
            tracing::info!(
                "vehicle granted SET_MESSAGE_INTERVAL: {}",
                granted.join(", ")
            );
        }
    }

    /// REQUEST_DATA_STREAM for what was refused (ArduPilot), or what is left to listen to.
    fn fallback(&self, id: &Identity) -> Vec<MavMessage> {
        let refused: Vec<&(Want, Answer)> = self
            .answers
            .iter()
            .filter(|(_, a)| *a != Answer::Granted)
            .collect();
        if refused.is_empty() {
            return Vec::new();
        }
        let names: Vec<String> = refused
            .iter()
            .map(|(w, a)| match a {
                Answer::Refused(r) => format!("{} ({r:?})", w.name),
                _ => format!("{} (no answer)", w.name),
            })
            .collect();
        if id.autopilot != Autopilot::ArduPilot {
            tracing::warn!(
                "vehicle did not grant SET_MESSAGE_INTERVAL for {}: listening at its own rates",
                names.join(", ")
            );
            return Vec::new();
        }
        let mut streams: BTreeMap<u8, (MavDataStream, f64)> = BTreeMap::new();
        for (w, _) in &refused {
            let e = streams.entry(w.stream as u8).or_insert((w.stream, 0.0));
            e.1 = e.1.max(w.hz);
        }
        tracing::warn!(
            "vehicle did not grant SET_MESSAGE_INTERVAL for {}: asked with REQUEST_DATA_STREAM ({}) instead",
            names.join(", "),
            streams
                .values()
                .map(|(s, hz)| format!("{s:?} {hz} Hz"))
                .collect::<Vec<_>>()
                .join(", ")
        );
        streams
            .values()
            .map(|&(stream, hz)| {
                MavMessage::REQUEST_DATA_STREAM(dialect::REQUEST_DATA_STREAM_DATA {
                    req_message_rate: hz.round() as u16,
                    target_system: id.system_id,
                    target_component: id.component_id,
                    req_stream_id: stream,
                    start_stop: 1,
                })
            })
            .collect()
    }

    fn say_seen(&self, t_s: f64) {
        let span = (t_s - self.count_from_s).max(1e-3);
        let seen: Vec<String> = self
            .answers
            .iter()
            .map(|(w, _)| {
                let hz = f64::from(self.heard.get(&w.id).copied().unwrap_or(0)) / span;
                format!("{} {hz:.1} Hz (asked {})", w.name, w.hz)
            })
            .collect();
        tracing::info!("rates seen: {}", seen.join(", "));
    }
}

/// MAV_CMD_SET_MESSAGE_INTERVAL for one message at its wanted rate.
fn set_interval(id: &Identity, w: &Want) -> MavMessage {
    MavMessage::COMMAND_LONG(dialect::COMMAND_LONG_DATA {
        param1: w.id as f32,
        param2: (1e6 / w.hz) as f32,
        param3: 0.0,
        param4: 0.0,
        param5: 0.0,
        param6: 0.0,
        param7: 0.0,
        command: MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
        target_system: id.system_id,
        target_component: id.component_id,
        confirmation: 0,
    })
}

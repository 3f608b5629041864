//! What kind of vehicle a sample is from: its class (multirotor, fixed-wing, VTOL, other),
//! the MAVLink `MAV_TYPE` it said in its HEARTBEAT, and for a VTOL the state it flies in
//! now (EXTENDED_SYS_STATE `vtol_state`, or ArduPlane's Q modes). The class picks the power
//! models that apply ([`VehicleKind::lift`]): rotor models for a multirotor and a VTOL
//! hovering or in transition, the fixed-wing model for a plane and a VTOL in forward
//! flight, none for anything else (rovers, boats, subs, unknown types).
//!
//! `MAV_TYPE` numbers are taken as numbers (the floor imports no dialect), named from
//! MAVLink's `common.xml` where known.

use std::fmt;

/// The vehicle class, as every output names it (`vehicle_class`).
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize, Hash,
)]
#[serde(rename_all = "snake_case")]
pub enum VehicleClass {
    /// Rotors only: quad, hexa, octo, tri, coaxial, helicopter, dodeca, deca, generic
    /// multirotor. Also what a vehicle is taken for before its HEARTBEAT says otherwise
    /// (the data set's M100 sends one that says quadrotor).
    #[default]
    Multirotor,
    /// A plane: wings carry it, a propeller pushes it.
    FixedWing,
    /// Both: hovers on rotors, cruises on wings (quadplane, tiltrotor, tailsitter).
    Vtol,
    /// Anything else (rover, boat, submarine, airship, an unknown type): no power model.
    Other,
}

impl VehicleClass {
    /// As JSON, the terminal and the config say it.
    pub fn as_str(self) -> &'static str {
        match self {
            VehicleClass::Multirotor => "multirotor",
            VehicleClass::FixedWing => "fixed_wing",
            VehicleClass::Vtol => "vtol",
            VehicleClass::Other => "other",
        }
    }
}

impl fmt::Display for VehicleClass {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A VTOL's flight state (MAVLink `MAV_VTOL_STATE`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub enum VtolState {
    /// Not said (not a VTOL, or no EXTENDED_SYS_STATE / Q mode heard).
    #[default]
    Undefined,
    /// Hovering or slow on the lift rotors (`MAV_VTOL_STATE_MC`, a Q mode).
    Mc,
    /// Forward flight on the wing (`MAV_VTOL_STATE_FW`).
    Fw,
    /// Changing from rotors to wing.
    TransitionToFw,
    /// Changing from wing to rotors.
    TransitionToMc,
}

impl VtolState {
    /// From `MAV_VTOL_STATE`'s number (0 and anything unknown: undefined).
    pub fn from_mav(n: u8) -> Self {
        match n {
            1 => VtolState::TransitionToFw,
            2 => VtolState::TransitionToMc,
            3 => VtolState::Mc,
            4 => VtolState::Fw,
            _ => VtolState::Undefined,
        }
    }

    /// As JSON and the terminal say it: `mc`, `fw`, `transition_to_fw`, `transition_to_mc`,
    /// `undefined`.
    pub fn as_str(self) -> &'static str {
        match self {
            VtolState::Undefined => "undefined",
            VtolState::Mc => "mc",
            VtolState::Fw => "fw",
            VtolState::TransitionToFw => "transition_to_fw",
            VtolState::TransitionToMc => "transition_to_mc",
        }
    }
}

/// How the vehicle is carried right now: what picks the power models.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Lift {
    /// Rotors carry it: the multirotor models (and the LSTM) apply.
    Rotor,
    /// The wing carries it: the fixed-wing model applies.
    Wing,
    /// Nothing dronewatt models (ground, water, an unknown type).
    Unmodelled,
}

/// The vehicle's kind at one sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub struct VehicleKind {
    /// The class.
    pub class: VehicleClass,
    /// The HEARTBEAT's `type` (MAV_TYPE) number, `None` before one is heard.
    pub mav_type: Option<u8>,
    /// A VTOL's state now ([`VtolState::Undefined`] for others).
    pub vtol_state: VtolState,
    /// The class comes from the config (`[vehicle] class`), not the HEARTBEAT.
    pub from_config: bool,
}

impl VehicleKind {
    /// Which model family applies now. A VTOL in transition counts as rotor-borne (the lift
    /// rotors still run; the multirotor models are allowed to be worse there), and a VTOL
    /// whose state is not yet known too (it takes off on its rotors).
    pub fn lift(&self) -> Lift {
        match (self.class, self.vtol_state) {
            (VehicleClass::Multirotor, _) => Lift::Rotor,
            (VehicleClass::FixedWing, _) | (VehicleClass::Vtol, VtolState::Fw) => Lift::Wing,
            (VehicleClass::Vtol, _) => Lift::Rotor,
            (VehicleClass::Other, _) => Lift::Unmodelled,
        }
    }

    /// The MAV_TYPE as people read it: `SUBMARINE (12)`, or `MAV_TYPE 99` for a number
    /// MAVLink does not define; `None` before a HEARTBEAT.
    pub fn mav_type_label(&self) -> Option<String> {
        self.mav_type.map(|t| match mav_type_name(t) {
            Some(name) => format!("{name} ({t})"),
            None => format!("MAV_TYPE {t}"),
        })
    }

    /// One line for people: `fixed_wing`, `vtol (fw)`, `other: SUBMARINE (12)`.
    pub fn describe(&self) -> String {
        match self.class {
            VehicleClass::Vtol => format!("vtol ({})", self.vtol_state.as_str()),
            VehicleClass::Other => match self.mav_type_label() {
                Some(t) => format!("other: {t}"),
                None => "other".to_string(),
            },
            c => c.as_str().to_string(),
        }
    }
}

/// The class a HEARTBEAT `type` says (MAVLink `MAV_TYPE`, common.xml).
pub fn class_of_mav_type(t: u8) -> VehicleClass {
    match t {
        // QUADROTOR, COAXIAL, HELICOPTER, HEXAROTOR, OCTOROTOR, TRICOPTER, DODECAROTOR,
        // DECAROTOR, GENERIC_MULTIROTOR.
        2 | 3 | 4 | 13 | 14 | 15 | 29 | 35 | 43 => VehicleClass::Multirotor,
        // FIXED_WING, FLAPPING_WING, KITE, PARAFOIL: a wing carries them.
        1 | 16 | 17 | 28 => VehicleClass::FixedWing,
        // VTOL_TAILSITTER_DUOROTOR … VTOL_RESERVED5, VTOL_GYRODYNE.
        19..=25 | 47 => VehicleClass::Vtol,
        _ => VehicleClass::Other,
    }
}

/// The class of a `MAV_TYPE` given by name (`MAV_TYPE_FIXED_WING` or `FIXED_WING`, as the
/// vehicle store keeps it); `other` for a name MAVLink does not define.
pub fn class_of_mav_type_name(name: &str) -> VehicleClass {
    let name = name.trim_start_matches("MAV_TYPE_");
    (0..=u8::MAX)
        .find(|&t| mav_type_name(t) == Some(name))
        .map_or(VehicleClass::Other, class_of_mav_type)
}

/// MAVLink's name for a `MAV_TYPE` number (without the `MAV_TYPE_` prefix), where it
/// defines one.
pub fn mav_type_name(t: u8) -> Option<&'static str> {
    const NAMES: [&str; 50] = [
        "GENERIC",
        "FIXED_WING",
        "QUADROTOR",
        "COAXIAL",
        "HELICOPTER",
        "ANTENNA_TRACKER",
        "GCS",
        "AIRSHIP",
        "FREE_BALLOON",
        "ROCKET",
        "GROUND_ROVER",
        "SURFACE_BOAT",
        "SUBMARINE",
        "HEXAROTOR",
        "OCTOROTOR",
        "TRICOPTER",
        "FLAPPING_WING",
        "KITE",
        "ONBOARD_CONTROLLER",
        "VTOL_TAILSITTER_DUOROTOR",
        "VTOL_TAILSITTER_QUADROTOR",
        "VTOL_TILTROTOR",
        "VTOL_FIXEDROTOR",
        "VTOL_TAILSITTER",
        "VTOL_TILTWING",
        "VTOL_RESERVED5",
        "GIMBAL",
        "ADSB",
        "PARAFOIL",
        "DODECAROTOR",
        "CAMERA",
        "CHARGING_STATION",
        "FLARM",
        "SERVO",
        "ODID",
        "DECAROTOR",
        "BATTERY",
        "PARACHUTE",
        "LOG",
        "OSD",
        "IMU",
        "GPS",
        "WINCH",
        "GENERIC_MULTIROTOR",
        "ILLUMINATOR",
        "SPACECRAFT_ORBITER",
        "GROUND_QUADRUPED",
        "VTOL_GYRODYNE",
        "GRIPPER",
        "RADIO",
    ];
    NAMES.get(usize::from(t)).copied()
}

/// ArduPlane's Q modes (HEARTBEAT `custom_mode` with MAV_AUTOPILOT_ARDUPILOTMEGA): QSTABILIZE
/// 17, QHOVER 18, QLOITER 19, QLAND 20, QRTL 21, QAUTOTUNE 22, QACRO 23, LOITER_ALT_QLAND 25.
/// In these a quadplane flies on its lift rotors.
pub fn arduplane_q_mode(custom_mode: u32) -> bool {
    matches!(custom_mode, 17..=23 | 25)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mav_types_classify() {
        assert_eq!(class_of_mav_type(2), VehicleClass::Multirotor);
        assert_eq!(class_of_mav_type(1), VehicleClass::FixedWing);
        assert_eq!(class_of_mav_type(21), VehicleClass::Vtol);
        assert_eq!(class_of_mav_type(12), VehicleClass::Other);
        assert_eq!(class_of_mav_type(200), VehicleClass::Other);
        let sub = VehicleKind {
            class: VehicleClass::Other,
            mav_type: Some(12),
            ..Default::default()
        };
        assert_eq!(sub.describe(), "other: SUBMARINE (12)");
        assert_eq!(sub.lift(), Lift::Unmodelled);
        let odd = VehicleKind {
            mav_type: Some(99),
            ..sub
        };
        assert_eq!(odd.mav_type_label().as_deref(), Some("MAV_TYPE 99"));
    }

    #[test]
    fn vtol_flies_on_what_carries_it() {
        let mut k = VehicleKind {
            class: VehicleClass::Vtol,
            ..Default::default()
        };
        assert_eq!(k.lift(), Lift::Rotor);
        k.vtol_state = VtolState::Fw;
        assert_eq!(k.lift(), Lift::Wing);
        k.vtol_state = VtolState::TransitionToMc;
        assert_eq!(k.lift(), Lift::Rotor);
    }
}

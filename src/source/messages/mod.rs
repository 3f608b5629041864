//! What MAVLink messages mean, apart from how they arrive: which senders are vehicles
//! ([`fleet`]), what a message says about the pack's power ([`power`]), and MAVLink's
//! fixed-size text fields as text. Pure: no I/O, no clocks.

pub mod fleet;
pub mod power;

/// A MAVLink name field (PARAM_VALUE's `param_id`, NAMED_VALUE_FLOAT's `name`) as text,
/// for the log writers; empty when it is not UTF-8.
pub fn name_text<const N: usize>(s: &mavlink::types::CharArray<N>) -> String {
    s.to_str().unwrap_or("").trim_end_matches('\0').to_string()
}

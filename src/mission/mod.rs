//! Missions: what the vehicle is asked to fly.
//!
//! [`guidance`] turns a list of waypoints (take-off, legs at their own speeds, holds,
//! landing) into the velocity a multirotor's position controller would command, step by
//! step; the simulator flies it, and anything that predicts a mission's energy can fly the
//! same route on paper.

pub mod guidance;

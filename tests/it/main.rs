//! The integration tests, as one test binary: each file is a module named after the module
//! or command of dronewatt it tests (`source_tlog` tests `source::logs::tlog`, `offline_plan` the
//! `plan` command, `cli_check_config` `check-config`). One binary links the crate and its
//! dependencies once instead of once a file (see "Test build" in docs/src/performance.md
//! for the times). Run one file's tests with `cargo test --test it source_tlog::`, one test
//! with its name. `tests/soak_short.rs` and `tests/sink_screen.rs` stay binaries of their
//! own: the soak's timing and RSS checks and the screen's pseudo-terminal want a process
//! to themselves.

// Shared helpers.
mod harness;
mod link_common;
mod mavlink_common;

mod alert;
mod alert_defaults;
mod assets_any_dir;
mod cli_check_config;
mod cli_replay;
mod config_paths;
mod demo_alerts;
mod energy_dataset;
mod energy_hover;
mod energy_pack;
mod energy_progpy;
mod energy_select;
mod features_units;
mod fleet_nats;
mod fleet_nats_auth;
mod fleet_nats_dashboard;
mod fleet_nats_restart;
mod fleet_nats_secured;
mod fuzz_props;
mod mission_fleet;
mod mission_margin;
mod mission_protocol;
mod model_adapt;
mod model_physics;
mod model_trees;
mod offline_learn;
mod offline_learn_dup;
mod offline_plan;
mod offline_plan_honest;
mod pack_any;
mod peer_multirotor;
mod pipeline_fleet;
mod readme_first_command;
mod replay_batches;
mod security;
mod sim_airframes;
mod sim_dataflash;
mod sim_fleet;
mod sim_physics;
mod sim_plane;
mod sim_tlog;
mod sim_udp;
mod sim_ulog;
mod sink_mavlink;
mod sink_mavlink_monitor;
mod sink_mqtt;
mod sink_web;
mod sink_web_replay;
mod source_dataset;
mod source_frame;
mod source_link;
mod source_link_faults;
mod source_links;
mod source_links_fast;
mod source_serial;
mod source_tlog;
mod source_tlog_corruption;
mod source_tlog_truncated;
mod source_ulog_fault;
mod start_fast;
mod telemetry;
mod telemetry_frames;
mod telemetry_link_rate;
mod telemetry_roundtrip;
mod vehicle_class;
mod vehicle_params;
mod vehicle_store;
mod vehicle_store_log_clock;
mod vehicle_store_two_vehicles;
mod views_pilot;

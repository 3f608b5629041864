//! Fuzz target: [`dronewatt::fuzz_props::check_plan`] on every input: the `.plan` and
//! `.waypoints` readers (the properties are documented there; `tests/it/fuzz_props.rs`
//! replays the corpus through the same check).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if let Err(e) = dronewatt::fuzz_props::check_plan(data) {
        panic!("property broken: {e}");
    }
});

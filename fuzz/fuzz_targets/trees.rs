//! Fuzz target: [`dronewatt::fuzz_props::check_trees`] on every input (the properties are
//! documented there; `tests/it/fuzz_props.rs` replays the corpus through the same check).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    if let Err(e) = dronewatt::fuzz_props::check_trees(data) {
        panic!("property broken: {e}");
    }
});

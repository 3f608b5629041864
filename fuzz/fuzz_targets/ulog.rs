//! Fuzz target: [`dronewatt::fuzz_props::check_ulog`] on every input (the properties
//! are documented there; `tests/it/fuzz_props.rs` replays the corpus through the same check).
//!
//! The `yule_log` parser panics on some malformed files; `decode_ulog` catches that and
//! returns an error. libFuzzer's panic hook aborts on every panic, caught or not, so the
//! hook here lets the parser's own panics unwind to that catch and still aborts on any
//! panic in dronewatt's code.
#![no_main]

libfuzzer_sys::fuzz_target!(
    init: {
        let abort = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !info.location().is_some_and(|l| l.file().contains("yule_log")) {
                abort(info);
            }
        }));
    },
    |data: &[u8]| {
        if let Err(e) = dronewatt::fuzz_props::check_ulog(data) {
            panic!("property broken: {e}");
        }
    }
);

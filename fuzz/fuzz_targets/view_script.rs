//! A viewer script as `view --script FILE` reads it: parsed, and on success its steps' total
//! time checked against the bound the parser promises. Any refusal is fine; a panic is not.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(script) = app::viewer::Script::parse(text, std::path::Path::new("fuzz.script")) {
        assert!(script.seconds() <= app::viewer::MAX_SCRIPT_SECONDS + 1e-9);
    }
});

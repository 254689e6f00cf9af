//! Fuzz target: the obj scene parser must return Ok or Err on any bytes, never panic.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    // An empty folder: referenced files are simply missing (warnings or errors).
    let dir = std::env::temp_dir().join("trayecto-fuzz-empty");
    let _ = std::fs::create_dir_all(&dir);
    let _ = &dir;
    let _ = trayecto::scene::load_bytes(data, &dir, "fuzz.obj");
});

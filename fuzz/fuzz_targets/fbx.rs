//! Fuzzes the binary FBX reader and its conversion to a scene: any input must give `Ok` or a
//! clean error, never a panic, an abort or unbounded memory.
//! Run: `cargo +nightly fuzz run fbx -- -max_len=200000` (seed the corpus with the shared .fbx files).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = trayecto::scene::fbx::load_bytes(data, "fuzz.fbx", None).and_then(|s| s.validate());
});

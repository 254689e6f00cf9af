//! Fuzzes the pbrt-v4 tokenizer, parser and graphics state: any input must give `Ok` or a clean
//! error, never a panic, an abort or unbounded memory. Text only: `Include`, `plymesh` and image
//! files are not read from memory (they are warnings), so the fuzzer cannot touch the disk.
//! Run: `cargo +nightly fuzz run pbrt -- -max_len=20000` (seed the corpus with
//! ../shared/scenes/pbrt/*/scene-v4.pbrt and scenes/pbrt/*.pbrt).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    // Validation is part of what a user's file goes through (scene::load_file does it).
    let _ = trayecto::scene::pbrt::load_from_bytes(data, "fuzz.pbrt").and_then(|s| s.validate());
});

//! Fuzz target: Mitsuba 3 XML scenes. Loads and builds the world (fuzz/entries.rs);
//! any input must give `Ok` or a clean error. Run: `scripts/fuzz.sh mitsuba 600` (docs/src/fuzzing.md).
#![no_main]

#[allow(dead_code)]
#[path = "../entries.rs"]
mod entries;

libfuzzer_sys::fuzz_target!(|data: &[u8]| entries::mitsuba(data));

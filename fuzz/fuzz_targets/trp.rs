//! Fuzz target: partial films (.trp), as `trayecto merge` reads them. Reads, merges and resolves the film (fuzz/entries.rs);
//! any input must give `Ok` or a clean error. Run: `scripts/fuzz.sh trp 600` (docs/src/fuzzing.md).
#![no_main]

#[allow(dead_code)]
#[path = "../entries.rs"]
mod entries;

libfuzzer_sys::fuzz_target!(|data: &[u8]| entries::trp(data));

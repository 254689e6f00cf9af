//! Fuzz target: the web server's render-request parser (fuzz/entries.rs); any input must be accepted or refused,
//! never a panic. Run: `scripts/fuzz.sh request 600` (docs/src/fuzzing.md).
#![no_main]

#[allow(dead_code)]
#[path = "../entries.rs"]
mod entries;

libfuzzer_sys::fuzz_target!(|data: &[u8]| entries::request(data));

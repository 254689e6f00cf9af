//! Fuzz target: the web server's render-request parser (`trayecto::server::request::
//! parse_request`) must accept or refuse any body, field by field, never panic; an accepted
//! request passes the renderer's own checks.
#![no_main]

use libfuzzer_sys::fuzz_target;
use trayecto::server::request::{Limits, Policy, parse_request};

fuzz_target!(|data: &[u8]| {
    // Built-in scenes only: no scenes folder, so no file is ever resolved.
    let policy = Policy {
        scenes_dir: None,
        output_dir: std::env::temp_dir(),
        limits: Limits {
            max_size: 64,
            max_spp: 16,
            ..Limits::default()
        },
        threads: Some(1),
    };
    if let Ok(r) = parse_request(data, &policy) {
        assert!(r.settings.validate().is_ok(), "{:?}", r.settings);
    }
});

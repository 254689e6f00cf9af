//! What `trayecto serve` checks before any work starts, kept in the library so that the fuzz
//! targets reach it (docs/DESIGN.md §7): render requests ([`request`]), uploaded scenes
//! ([`upload`]) and names resolved inside the scenes folder ([`folder`]). The web server itself
//! (routes, jobs, previews) is the binary's, a front end over these.

pub mod folder;
pub mod request;
pub mod upload;

//! Trayecto as a library: load a scene, compile it, render it, write the image.
//! `cargo run --release --example library [SCENE] [OUT]` (defaults: the built-in Cornell box,
//! library.png). The guide's chapter "Using Trayecto as a library" shows this file.
use std::error::Error;
use std::path::Path;
use std::sync::atomic::AtomicBool;

use trayecto::film::output::write_image;
use trayecto::film::tonemap::Tonemap;
use trayecto::render::{NoObserver, RenderSettings, render};
use trayecto::scene;
use trayecto::world::{World, WorldOptions};

fn main() -> Result<(), Box<dyn Error>> {
    let mut args = std::env::args().skip(1);
    let spec = args.next().unwrap_or_else(|| "cornell".into());
    let out = args.next().unwrap_or_else(|| "library.png".into());

    // A file path (glTF, OBJ, PLY, FBX, pbrt, TOML) or a built-in scene's name.
    let scene = scene::load(&spec)?;
    let world = World::build(scene, &WorldOptions::default())?;
    let settings = RenderSettings {
        width: 256,
        height: 256,
        spp: 16,
        ..RenderSettings::default()
    };
    // Set the flag from another thread to cancel; the observer sees every finished pass.
    let cancel = AtomicBool::new(false);
    let result = render(&world, &settings, &NoObserver, &cancel)?;
    write_image(&result.image, Path::new(&out), 1.0, Tonemap::Clamp)?;
    println!(
        "{out}: {} spp in {:.2} s, {:.1} Mrays/s",
        settings.spp,
        result.render_time.as_secs_f64(),
        result.rays_per_second() / 1e6
    );
    Ok(())
}

//! When a scene gets the default environment: the studio environment ([`super::studio`]), or
//! with `--default-light uniform` a uniform white sky of radiance 1 (the earlier default).
//!
//! Model files (glTF sample models, most assets from the wild) carry no lights: a model viewer
//! lights them with an environment. Many of them do carry *emissive* surfaces — the lit visor of
//! DamagedHelmet, ToyCar's and TransmissionTest's labels, StainedGlassLamp's glowing glass — and
//! a path tracer rightly counts those as area lights. Before this rule, any emitter suppressed the
//! default light and such models rendered almost black.
//!
//! # The rule (`--default-light auto`, the default)
//!
//! The default environment is added when the scene has no lights, **or** when its only lights are
//! emissive surfaces that are *self-lit*, which takes both of:
//! 1. their peak emitted radiance (emissive factor × strength × the brightest texel of the
//!    emissive texture) is at most 1 in every channel, and
//! 2. their total power is under a tenth of what the default environment would send into the
//!    scene's bounding sphere ([`EmitterStats::power_ratio`] < [`SELF_LIT_MAX_POWER_RATIO`]).
//!
//! Why 1: the default environment has radiance 1, so a white Lambertian surface lit by it has
//! outgoing radiance 1. An emitter no brighter than that is, to the rest of the scene, no brighter
//! than a white wall in the viewer's light — a decal, a screen, a label, not a lamp — and cannot be
//! what the author meant to light the scene with. It is also exactly the ceiling of core glTF 2.0:
//! `emissiveFactor` is limited to [0, 1], and an exporter has to write
//! `KHR_materials_emissive_strength` (or another format its own light units) to make a surface that
//! lights a room. A lamp — a Cornell box's ceiling light (radiance ≈ 17), an OBJ `Ke` light, a
//! Blender emission shader exported with its strength — is brighter than 1 and keeps the scene's
//! own lighting unchanged.
//!
//! Why the power test as well: dim emitters can still be the whole lighting when there are many of
//! them — walls that glow all around the camera (the white-furnace scenes), a large light panel.
//! Their power then rivals the environment's, and adding a sky would change what the author built
//! (or, in a closed room, only add noise). Decals cover a small part of a model and are mostly
//! dark texels: their power is a percent or less of the environment's. Scenes with any point,
//! spot, directional, ambient or environment light are never changed.
//!
//! The thresholds below are measured against the uniform sky of radiance 1 whichever environment
//! is added (the studio's brightest side lights a white surface to about the same radiance).
//!
//! `--default-light on` adds the default environment unless the scene already has a light at
//! infinity (ambient or environment map: it would only be doubled); `off` never adds it.

use crate::light::{AreaLight, Light};
use crate::material::{Material, Texture};
use crate::math::{PI, Vec3, luminance};

pub use crate::scene::DefaultLight;

/// Emitted radiance at or below this (per channel) is "self-lit"; the small margin absorbs
/// factors such as 1.0000001 written by exporters.
pub const SELF_LIT_MAX_RADIANCE: f32 = 1.0 + 1e-4;

/// The brightest radiance a material can emit: its factor times the brightest texel of its
/// emissive texture (a missing texture index counts as white, as validation rejects it anyway).
pub fn peak_emission(material: &Material, textures: &[Texture]) -> Vec3 {
    let mut e = material.emissive;
    if let Some(t) = &material.emissive_texture {
        let max = textures
            .get(t.texture)
            .map(|tex| {
                // Storage order: a tiled texture's padding repeats its own texels.
                tex.texels
                    .iter()
                    .fold(Vec3::ZERO, |m, texel| m.max(texel.truncate()))
            })
            .unwrap_or(Vec3::ONE);
        e *= max;
    }
    e
}

/// What the rule needs to know about a scene's emissive surfaces.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct EmitterStats {
    /// The brightest radiance any emissive surface can emit (max over channels of
    /// [`peak_emission`]).
    pub peak_radiance: f32,
    /// The emitters' total power over the power the default environment sends into the scene's
    /// bounding sphere: Σ sides·A·lum(L̄) / (4π r²) (both powers carry the same factor π of a
    /// Lambertian emitter, so it cancels). L̄ is the emission averaged over the texture.
    pub power_ratio: f32,
    /// Up to four emissive material names, for the message.
    pub names: Vec<String>,
}

/// Emitters whose power is at least this fraction of the default environment's (see
/// [`EmitterStats::power_ratio`]) light the scene themselves even when each is no brighter than
/// radiance 1: a scene enclosed by emissive walls (a furnace) or a large glowing panel. Measured
/// (`tests/default_light.rs` checks them): the decal models are at most 0.011 (DamagedHelmet
/// 0.00095, ToyCar 0.0022, TransmissionTest 0.011, LightsPunctualLamp's emissive bulbs 0.014),
/// the emissive sphere and box furnaces of `tests/path_estimator.rs` 0.33 and 0.32 (and lamps
/// that pass test 1 anyway: the built-in Cornell box 0.067, the OBJ Cornell box 0.094).
pub const SELF_LIT_MAX_POWER_RATIO: f32 = 0.1;

/// Summarises the area lights among `lights` (`area_of(light index)` gives each one's area).
pub fn emitter_stats(
    lights: &[Light],
    materials: &[Material],
    textures: &[Texture],
    area_of: impl Fn(usize) -> f32,
    scene_radius: f32,
) -> EmitterStats {
    let mut peak = vec![None::<f32>; materials.len()];
    let mut average = vec![None::<f32>; materials.len()];
    let mut stats = EmitterStats::default();
    let mut weighted_area = 0.0f64;
    for (i, l) in lights.iter().enumerate() {
        let Light::Area(AreaLight { material, .. }) = l else {
            continue;
        };
        let Some(m) = materials.get(*material as usize) else {
            continue;
        };
        let k = *material as usize;
        let p = *peak[k].get_or_insert_with(|| peak_emission(m, textures).max_element());
        let a = *average[k].get_or_insert_with(|| {
            let mut e = m.emissive;
            if let Some(t) = &m.emissive_texture {
                e *= textures
                    .get(t.texture)
                    .map(|tex| tex.average().truncate())
                    .unwrap_or(Vec3::ONE);
            }
            luminance(e)
        });
        stats.peak_radiance = stats.peak_radiance.max(p);
        let name = format!("'{}'", m.name);
        if stats.names.len() < 4 && !stats.names.contains(&name) {
            stats.names.push(name);
        }
        let sides = if m.double_sided { 2.0 } else { 1.0 };
        weighted_area += (sides * area_of(i) * a) as f64;
    }
    let sphere = 4.0 * PI * scene_radius.max(1e-6).powi(2);
    stats.power_ratio = (weighted_area / sphere as f64) as f32;
    stats
}

/// What the rule decided, and a sentence saying why (reported as a warning when the light is
/// added, or when a scene without lights is left black).
#[derive(Clone, Debug, PartialEq)]
pub struct Decision {
    pub add: bool,
    pub reason: String,
}

/// Applies the rule to the lights the scene brings (area lights included), given
/// [`emitter_stats`] of its area lights.
pub fn decide(mode: DefaultLight, lights: &[Light], emitters: &EmitterStats) -> Decision {
    let has_infinite_fill = lights
        .iter()
        .any(|l| matches!(l, Light::Uniform(_) | Light::Environment(_)));
    let keep = || Decision {
        add: false,
        reason: String::new(),
    };
    let what = if mode == DefaultLight::Uniform {
        "a uniform white environment (radiance 1)"
    } else {
        "the studio environment (--default-light uniform: a uniform white one)"
    };
    match mode {
        DefaultLight::Off => Decision {
            add: false,
            reason: if lights.is_empty() {
                "the scene has no lights and --default-light is off: it renders black".into()
            } else {
                String::new()
            },
        },
        DefaultLight::On if has_infinite_fill => keep(),
        DefaultLight::On => Decision {
            add: true,
            reason: format!("--default-light on: adding {what}"),
        },
        DefaultLight::Auto | DefaultLight::Uniform if lights.is_empty() => Decision {
            add: true,
            reason: format!(
                "the scene has no lights: lighting it with {what}; --default-light off renders \
                 it unlit"
            ),
        },
        // Any light that is not an emissive surface is the author's lighting.
        DefaultLight::Auto | DefaultLight::Uniform
            if lights.iter().any(|l| !matches!(l, Light::Area(_))) =>
        {
            keep()
        }
        DefaultLight::Auto | DefaultLight::Uniform
            if emitters.peak_radiance <= SELF_LIT_MAX_RADIANCE
                && emitters.power_ratio < SELF_LIT_MAX_POWER_RATIO =>
        {
            Decision {
                add: true,
                reason: format!(
                    "the scene's only lights are self-lit emissive surfaces ({}: peak radiance \
                     {:.3} <= 1, total power {:.4} of the default environment's < {}): lighting \
                     it with {what} as a model viewer does; --default-light off renders it by \
                     its emitters alone",
                    emitters.names.join(", "),
                    emitters.peak_radiance,
                    emitters.power_ratio,
                    SELF_LIT_MAX_POWER_RATIO
                ),
            }
        }
        DefaultLight::Auto | DefaultLight::Uniform => keep(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::primitive::{PrimRef, PrimitiveKind};
    use crate::material::TextureRef;
    use crate::math::Vec4;

    fn area(material: u32) -> Light {
        Light::Area(AreaLight::new(
            PrimRef::new(PrimitiveKind::Triangle, 0),
            material,
        ))
    }

    fn emitter(e: Vec3) -> Material {
        Material {
            emissive: e,
            ..Material::diffuse("e", Vec3::splat(0.5))
        }
    }

    fn stats(lights: &[Light], materials: &[Material], textures: &[Texture]) -> EmitterStats {
        // Unit-area emitters in a scene of radius 1: power ratio = Σ sides·lum / 4π.
        emitter_stats(lights, materials, textures, |_| 1.0, 1.0)
    }

    fn auto(lights: &[Light], materials: &[Material], textures: &[Texture]) -> Decision {
        decide(
            DefaultLight::Auto,
            lights,
            &stats(lights, materials, textures),
        )
    }

    #[test]
    fn lamps_keep_the_scene_as_is_and_decals_get_the_environment() {
        let lamp = [emitter(Vec3::new(17.0, 12.0, 4.0))];
        assert!(!auto(&[area(0)], &lamp, &[]).add);
        let decal = [emitter(Vec3::splat(0.5))];
        let d = auto(&[area(0)], &decal, &[]);
        assert!(d.add && d.reason.contains("self-lit"), "{d:?}");
        // One lamp among decals is enough to count as the author's lighting.
        let both = [emitter(Vec3::splat(0.5)), emitter(Vec3::splat(2.0))];
        assert!(!auto(&[area(0), area(1)], &both, &[]).add);
        // A material with a bright factor that no area light uses does not count.
        assert!(auto(&[area(0)], &both, &[]).add);
    }

    #[test]
    fn many_dim_emitters_are_the_lighting() {
        // Radiance 1 over unit area: power ratio 1/4π ≈ 0.08, under the threshold...
        let dim = [emitter(Vec3::ONE)];
        let one = stats(&[area(0)], &dim, &[]);
        assert!((one.power_ratio - 1.0 / (4.0 * PI)).abs() < 1e-6, "{one:?}");
        assert!(decide(DefaultLight::Auto, &[area(0)], &one).add);
        // ... two of them are over it (a glowing enclosure, a furnace).
        let two = [area(0), area(0)];
        assert!(!auto(&two, &dim, &[]).add);
        // Double-sided emitters count both sides.
        let mut double = emitter(Vec3::ONE);
        double.double_sided = true;
        assert!(!auto(&[area(0)], &[double], &[]).add);
    }

    #[test]
    fn the_emissive_texture_peak_counts() {
        let mut m = emitter(Vec3::splat(4.0));
        m.emissive_texture = Some(TextureRef::new(0));
        let dim = Texture::constant("dim", Vec4::new(0.2, 0.1, 0.25, 1.0));
        let s = stats(&[area(0)], &[m.clone()], &[dim]);
        assert!((s.peak_radiance - 1.0).abs() < 1e-6, "{s:?}");
        assert!(decide(DefaultLight::Auto, &[area(0)], &s).add);
        // One bright texel makes it a lamp, whatever the average.
        let bright = Texture::image(
            "bright",
            2,
            1,
            vec![Vec4::new(0.0, 0.0, 0.0, 1.0), Vec4::new(0.0, 0.3, 0.0, 1.0)],
        );
        assert!(!auto(&[area(0)], &[m], &[bright]).add);
    }

    #[test]
    fn other_lights_and_modes() {
        let none: [Light; 0] = [];
        let empty = EmitterStats::default();
        assert!(decide(DefaultLight::Auto, &none, &empty).add);
        assert!(!decide(DefaultLight::Off, &none, &empty).add);
        let point = Light::Point(crate::light::PointLight {
            position: Vec3::ZERO,
            intensity: Vec3::splat(0.1),
        });
        assert!(!decide(DefaultLight::Auto, std::slice::from_ref(&point), &empty).add);
        assert!(decide(DefaultLight::On, &[point], &empty).add);
        let sky = Light::Uniform(crate::light::UniformLight {
            radiance: Vec3::splat(0.3),
        });
        assert!(!decide(DefaultLight::On, &[sky], &empty).add);
        let lamp = [emitter(Vec3::splat(10.0))];
        let s = stats(&[area(0)], &lamp, &[]);
        assert!(decide(DefaultLight::On, &[area(0)], &s).add);
        let decal = [emitter(Vec3::splat(0.5))];
        let s = stats(&[area(0)], &decal, &[]);
        assert!(!decide(DefaultLight::Off, &[area(0)], &s).add);
        assert!(decide(DefaultLight::Uniform, &none, &empty).add);
        for m in [
            DefaultLight::Auto,
            DefaultLight::On,
            DefaultLight::Off,
            DefaultLight::Uniform,
        ] {
            assert_eq!(DefaultLight::parse(m.name()), Some(m));
        }
        assert_eq!(DefaultLight::parse("yes"), None);
    }
}

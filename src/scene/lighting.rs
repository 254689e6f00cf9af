//! What a scene says about its lighting beyond the lights themselves: how an environment image
//! covers the sphere and whether the default environment is wanted. Plain data the loaders fill
//! and `light/` reads (docs/DESIGN.md, "Layers": descriptions live below what compiles them).

/// How an environment image covers the sphere.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum EnvMapping {
    /// Latitude–longitude (Mitsuba's convention, +y up).
    #[default]
    Equirectangular,
    /// pbrt-v4's equal-area octahedral square (+z is the square's centre).
    EqualArea,
}

/// How the default environment is chosen (`--default-light`, the TOML `default_light` key, the
/// web UI's "default light" choice).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DefaultLight {
    /// Add it when the scene has no lights or only self-lit emitters (the rule is in
    /// `light::default_light`).
    #[default]
    Auto,
    /// Add it unless the scene already has an ambient or environment light.
    On,
    /// Never add it.
    Off,
    /// As `Auto`, but the environment added is the uniform white sky of radiance 1 (the default
    /// before the studio environment; references and furnace-style checks ask for it).
    Uniform,
}

impl DefaultLight {
    pub fn name(self) -> &'static str {
        match self {
            DefaultLight::Auto => "auto",
            DefaultLight::On => "on",
            DefaultLight::Off => "off",
            DefaultLight::Uniform => "uniform",
        }
    }

    pub fn parse(s: &str) -> Option<DefaultLight> {
        match s {
            "auto" => Some(DefaultLight::Auto),
            "on" => Some(DefaultLight::On),
            "off" => Some(DefaultLight::Off),
            "uniform" => Some(DefaultLight::Uniform),
            _ => None,
        }
    }
}

impl std::str::FromStr for DefaultLight {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        DefaultLight::parse(s).ok_or_else(|| format!("'{s}' is not one of: auto, on, off, uniform"))
    }
}

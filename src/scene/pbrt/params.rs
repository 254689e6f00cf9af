//! Typed parameter lists (`"float fov" [ 35 ]`, `"rgb L" [1 1 1]`, `"spectrum eta" "metal-Cu-eta"`,
//! `"texture reflectance" "wood"` …), pbrt-v4 `paramdict.cpp` semantics: a single value may be
//! written without brackets, numbers are bare, strings quoted, bools `true`/`false` (bare or
//! quoted). Every lookup marks the parameter used, so the importer can warn about each parameter it
//! did not read instead of dropping it silently.

use std::cell::Cell;

use crate::math::{Vec2, Vec3};

/// The raw values of one parameter.
#[derive(Clone, Debug, PartialEq)]
pub enum Values {
    Nums(Vec<f64>),
    Strs(Vec<String>),
    Bools(Vec<bool>),
}

impl Values {
    fn len(&self) -> usize {
        match self {
            Values::Nums(v) => v.len(),
            Values::Strs(v) => v.len(),
            Values::Bools(v) => v.len(),
        }
    }
}

#[derive(Clone, Debug)]
pub struct Param {
    /// The declared type (`float`, `rgb`, `point3`, …), `normal3` and `vector` folded to their
    /// pbrt-v4 names.
    pub ty: String,
    pub name: String,
    pub values: Values,
    pub used: Cell<bool>,
}

/// The types pbrt-v4 knows.
pub const TYPES: &[&str] = &[
    "float",
    "integer",
    "point2",
    "vector2",
    "point3",
    "vector3",
    "normal",
    "bool",
    "string",
    "rgb",
    "spectrum",
    "blackbody",
    "texture",
];

/// How many numbers one element of a type takes (1 for scalars).
fn arity(ty: &str) -> usize {
    match ty {
        "point2" | "vector2" => 2,
        "point3" | "vector3" | "normal" | "rgb" => 3,
        _ => 1,
    }
}

impl Param {
    pub fn new(decl: &str, values: Values) -> Result<Param, String> {
        let words: Vec<&str> = decl.split_whitespace().collect();
        let [ty, name] = words.as_slice() else {
            return Err(format!(
                "'{}' is not a parameter declaration (\"type name\")",
                short(decl)
            ));
        };
        let ty = match *ty {
            "point" => "point3",
            "vector" => "vector3",
            "normal3" => "normal",
            "color" => "rgb",
            "bool" => "bool",
            t => t,
        };
        if !TYPES.contains(&ty) {
            return Err(format!("unknown parameter type '{}'", short(ty)));
        }
        // Bools may be written quoted ("true") or bare (true).
        let values = if ty == "bool" {
            let words: Vec<String> = match values {
                Values::Strs(s) => s,
                Values::Bools(b) => b.into_iter().map(|b| b.to_string()).collect(),
                Values::Nums(_) => {
                    return Err(format!("bool parameter '{name}' has a number value"));
                }
            };
            let mut out = Vec::with_capacity(words.len());
            for w in words {
                out.push(match w.as_str() {
                    "true" => true,
                    "false" => false,
                    other => {
                        return Err(format!(
                            "bool parameter '{name}' has value '{}' (true or false expected)",
                            short(other)
                        ));
                    }
                });
            }
            Values::Bools(out)
        } else {
            values
        };
        let string_typed = matches!(ty, "string" | "texture");
        match (&values, ty) {
            (Values::Strs(_), _) if string_typed || ty == "spectrum" => {}
            (Values::Nums(_), _) if !string_typed && ty != "bool" => {}
            (Values::Bools(_), "bool") => {}
            _ => {
                return Err(format!(
                    "parameter '{ty} {name}' has values of the wrong kind"
                ));
            }
        }
        if values.len() == 0 {
            return Err(format!("parameter '{ty} {name}' has no values"));
        }
        let n = arity(ty);
        if let Values::Nums(v) = &values {
            if v.len() % n != 0 {
                return Err(format!(
                    "parameter '{ty} {name}' has {} values, not a multiple of {n}",
                    v.len()
                ));
            }
            if ty == "integer" && v.iter().any(|x| x.fract() != 0.0) {
                return Err(format!(
                    "integer parameter '{name}' has a non-integer value"
                ));
            }
            // pbrt-v4 reads integers as 32-bit `int`s.
            if ty == "integer"
                && let Some(x) = v
                    .iter()
                    .find(|x| !(-2_147_483_648.0..=2_147_483_647.0).contains(*x))
            {
                return Err(format!(
                    "integer parameter '{name}' has the value {x}, outside the 32-bit range (-2147483648 to 2147483647)"
                ));
            }
            if let Some(bad) = v.iter().find(|x| !x.is_finite()) {
                return Err(format!("parameter '{ty} {name}' has the value {bad}"));
            }
            // A sampled spectrum is (λ, value) pairs with λ increasing; pbrt-v4 stops on
            // either fault (paramdict.cpp), where reading on would drop a number or sort the
            // table silently.
            if ty == "spectrum" {
                if v.len() % 2 != 0 {
                    return Err(format!(
                        "parameter 'spectrum {name}' has {} values: a sampled spectrum is (wavelength, value) pairs",
                        v.len()
                    ));
                }
                if let Some(i) = (2..v.len()).step_by(2).find(|&i| v[i] <= v[i - 2]) {
                    return Err(format!(
                        "parameter 'spectrum {name}': the wavelengths do not increase ({} then {})",
                        v[i - 2],
                        v[i]
                    ));
                }
            }
        }
        Ok(Param {
            ty: ty.to_string(),
            name: name.to_string(),
            values,
            used: Cell::new(false),
        })
    }
}

impl Param {
    /// What pbrt-v4 warns about in a parameter that is otherwise valid: a sampled spectrum of a
    /// single (λ, value) pair is non-zero at that one wavelength, which is probably unintended.
    pub fn doubt(&self) -> Option<String> {
        match (&self.ty[..], &self.values) {
            ("spectrum", Values::Nums(v)) if v.len() == 2 => Some(format!(
                "\"spectrum {}\" is non-zero only at {} nm (a single wavelength, value pair): probably unintended",
                self.name, v[0]
            )),
            _ => None,
        }
    }
}

fn short(s: &str) -> String {
    if s.chars().count() > 40 {
        format!("{}…", s.chars().take(40).collect::<String>())
    } else {
        s.to_string()
    }
}

/// A spectral value as written: RGB, a blackbody temperature, a named spectrum or sampled
/// (λ, value) pairs.
#[derive(Clone, Debug, PartialEq)]
pub enum SpectrumValue {
    Rgb(Vec3),
    Blackbody(f32),
    Named(String),
    Sampled(Vec<(f32, f32)>),
}

/// A parameter that is either a constant or a named texture.
#[derive(Clone, Debug, PartialEq)]
pub enum TexOr<T> {
    Value(T),
    Texture(String),
}

#[derive(Clone, Debug, Default)]
pub struct ParamList {
    pub params: Vec<Param>,
}

impl ParamList {
    pub fn push(&mut self, p: Param) -> Result<(), String> {
        if self.params.iter().any(|q| q.name == p.name) {
            return Err(format!("parameter '{}' is given twice", p.name));
        }
        self.params.push(p);
        Ok(())
    }

    fn find(&self, name: &str, types: &[&str]) -> Option<&Param> {
        let p = self
            .params
            .iter()
            .find(|p| p.name == name && types.contains(&p.ty.as_str()))?;
        p.used.set(true);
        Some(p)
    }

    pub fn has(&self, name: &str) -> bool {
        self.params.iter().any(|p| p.name == name)
    }

    pub fn floats(&self, name: &str) -> Option<Vec<f32>> {
        match &self.find(name, &["float"])?.values {
            Values::Nums(v) => Some(v.iter().map(|&x| x as f32).collect()),
            _ => None,
        }
    }

    pub fn float(&self, name: &str, default: f32) -> f32 {
        self.floats(name)
            .and_then(|v| v.first().copied())
            .unwrap_or(default)
    }

    pub fn ints(&self, name: &str) -> Option<Vec<i64>> {
        match &self.find(name, &["integer"])?.values {
            Values::Nums(v) => Some(v.iter().map(|&x| x as i64).collect()),
            _ => None,
        }
    }

    pub fn int(&self, name: &str, default: i64) -> i64 {
        self.ints(name)
            .and_then(|v| v.first().copied())
            .unwrap_or(default)
    }

    pub fn bool(&self, name: &str, default: bool) -> bool {
        match self.find(name, &["bool"]).map(|p| &p.values) {
            Some(Values::Bools(b)) => b.first().copied().unwrap_or(default),
            _ => default,
        }
    }

    pub fn string(&self, name: &str) -> Option<String> {
        match &self.find(name, &["string"])?.values {
            Values::Strs(v) => v.first().cloned(),
            _ => None,
        }
    }

    pub fn strings(&self, name: &str) -> Option<Vec<String>> {
        match &self.find(name, &["string"])?.values {
            Values::Strs(v) => Some(v.clone()),
            _ => None,
        }
    }

    fn nums(&self, name: &str, types: &[&str]) -> Option<&[f64]> {
        match &self.find(name, types)?.values {
            Values::Nums(v) => Some(v),
            _ => None,
        }
    }

    pub fn point3s(&self, name: &str) -> Option<Vec<Vec3>> {
        let v = self.nums(name, &["point3", "vector3", "normal"])?;
        Some(
            v.chunks_exact(3)
                .map(|c| Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32))
                .collect(),
        )
    }

    pub fn point3(&self, name: &str, default: Vec3) -> Vec3 {
        self.point3s(name)
            .and_then(|v| v.first().copied())
            .unwrap_or(default)
    }

    pub fn point2s(&self, name: &str) -> Option<Vec<Vec2>> {
        let v = self.nums(name, &["point2", "vector2"])?;
        Some(
            v.chunks_exact(2)
                .map(|c| Vec2::new(c[0] as f32, c[1] as f32))
                .collect(),
        )
    }

    /// A spectrum-valued parameter (`rgb`, `blackbody`, `spectrum`).
    pub fn spectrum(&self, name: &str) -> Option<SpectrumValue> {
        let p = self.find(name, &["rgb", "blackbody", "spectrum"])?;
        match (&p.ty[..], &p.values) {
            ("rgb", Values::Nums(v)) => Some(SpectrumValue::Rgb(Vec3::new(
                v[0] as f32,
                v[1] as f32,
                v[2] as f32,
            ))),
            ("blackbody", Values::Nums(v)) => Some(SpectrumValue::Blackbody(v[0] as f32)),
            ("spectrum", Values::Strs(s)) => Some(SpectrumValue::Named(s[0].clone())),
            ("spectrum", Values::Nums(v)) => Some(SpectrumValue::Sampled(
                v.chunks_exact(2)
                    .map(|c| (c[0] as f32, c[1] as f32))
                    .collect(),
            )),
            _ => None,
        }
    }

    /// A float parameter or a float texture reference.
    pub fn float_tex(&self, name: &str) -> Option<TexOr<f32>> {
        if let Some(t) = self.texture(name) {
            return Some(TexOr::Texture(t));
        }
        self.floats(name)
            .and_then(|v| v.first().copied())
            .map(TexOr::Value)
    }

    /// A spectrum parameter or a spectrum texture reference.
    pub fn spectrum_tex(&self, name: &str) -> Option<TexOr<SpectrumValue>> {
        if let Some(t) = self.texture(name) {
            return Some(TexOr::Texture(t));
        }
        self.spectrum(name).map(TexOr::Value)
    }

    pub fn texture(&self, name: &str) -> Option<String> {
        match &self.find(name, &["texture"])?.values {
            Values::Strs(v) => v.first().cloned(),
            _ => None,
        }
    }

    /// Parameters nobody looked up, as `"type name"`.
    pub fn unused(&self) -> Vec<String> {
        self.params
            .iter()
            .filter(|p| !p.used.get())
            .map(|p| format!("\"{} {}\"", p.ty, p.name))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn declarations_are_checked() {
        assert!(Param::new("float", Values::Nums(vec![1.0])).is_err());
        assert!(Param::new("quaternion q", Values::Nums(vec![1.0])).is_err());
        assert!(Param::new("rgb L", Values::Nums(vec![1.0, 2.0])).is_err());
        assert!(Param::new("integer n", Values::Nums(vec![1.5])).is_err());
        assert!(Param::new("float x", Values::Nums(vec![f64::NAN])).is_err());
        assert!(Param::new("float x", Values::Strs(vec!["a".into()])).is_err());
        let b = Param::new("bool b", Values::Strs(vec!["true".into()])).unwrap();
        assert_eq!(b.values, Values::Bools(vec![true]));
    }

    #[test]
    fn lookups_mark_parameters_used() {
        let mut l = ParamList::default();
        l.push(Param::new("float fov", Values::Nums(vec![35.0])).unwrap())
            .unwrap();
        l.push(Param::new("rgb L", Values::Nums(vec![1.0, 2.0, 3.0])).unwrap())
            .unwrap();
        assert!(
            l.push(Param::new("float fov", Values::Nums(vec![1.0])).unwrap())
                .is_err()
        );
        assert_eq!(l.float("fov", 90.0), 35.0);
        assert_eq!(l.unused(), vec!["\"rgb L\"".to_string()]);
        assert_eq!(
            l.spectrum("L"),
            Some(SpectrumValue::Rgb(Vec3::new(1.0, 2.0, 3.0)))
        );
        assert!(l.unused().is_empty());
    }
}

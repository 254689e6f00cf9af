//! A content digest of a scene, so partial films rendered apart can be checked to come from the
//! same scene even when each machine sees it at a different path (a shared filesystem mounted
//! elsewhere, an uploaded bundle).
//!
//! SHA-256 over the scene file's bytes, then over everything the loader produced from it and the
//! files it references (mesh data, texture texels, materials, objects, lights, cameras) and the
//! bytes of environment maps. Names and paths are left out: they do not change the image.

use super::{LightDesc, Scene, SceneError};
use sha2::{Digest, Sha256};
use std::path::Path;

fn hash_file(h: &mut Sha256, path: &Path) -> Result<(), SceneError> {
    let io = |source| SceneError::Io {
        path: path.display().to_string(),
        error: source,
    };
    let mut f = std::fs::File::open(path).map_err(io)?;
    std::io::copy(&mut f, h).map_err(io)?;
    Ok(())
}

fn hash_f32s<V: std::borrow::Borrow<f32>>(h: &mut Sha256, values: impl Iterator<Item = V>) {
    let mut buf = Vec::with_capacity(4096);
    for v in values {
        buf.extend_from_slice(&v.borrow().to_bits().to_le_bytes());
        if buf.len() >= 4096 {
            h.update(&buf);
            buf.clear();
        }
    }
    h.update(&buf);
}

fn hash_debug(h: &mut Sha256, v: &impl std::fmt::Debug) {
    h.update(format!("{v:?}").as_bytes());
    h.update([0]);
}

/// The hex SHA-256 digest of the scene named `spec` (a file or a built-in name) as loaded into
/// `scene`, lit by the environment map `env` if given.
pub fn digest(spec: &str, scene: &Scene, env: Option<&Path>) -> Result<String, SceneError> {
    let mut h = Sha256::new();
    h.update(b"trayecto-scene-digest-1\0");
    let path = Path::new(spec);
    if path.is_file() {
        hash_file(&mut h, path)?;
    } else {
        h.update(spec.as_bytes());
    }
    h.update(b"\0meshes");
    for m in &scene.meshes {
        h.update((m.positions.len() as u64).to_le_bytes());
        hash_f32s(&mut h, m.positions.iter().flat_map(|p| p.as_ref().iter()));
        h.update((m.indices.len() as u64).to_le_bytes());
        for t in &m.indices {
            for i in t {
                h.update(i.to_le_bytes());
            }
        }
        let flag = |h: &mut Sha256, present: bool| h.update([present as u8]);
        flag(&mut h, m.normals.is_some());
        if let Some(n) = &m.normals {
            hash_f32s(&mut h, n.iter().flat_map(|p| p.as_ref().iter()));
        }
        flag(&mut h, m.tangents.is_some());
        if let Some(n) = &m.tangents {
            hash_f32s(&mut h, n.iter().flat_map(|p| p.as_ref().iter()));
        }
        for uv in [&m.uv0, &m.uv1] {
            flag(&mut h, uv.is_some());
            if let Some(n) = uv {
                hash_f32s(&mut h, n.iter().flat_map(|p| p.as_ref().iter()));
            }
        }
        flag(&mut h, m.colors.is_some());
        if let Some(n) = &m.colors {
            hash_f32s(&mut h, n.iter().flat_map(|p| p.as_ref().iter()));
        }
    }
    h.update(b"\0textures");
    for t in &scene.textures {
        h.update(t.width.to_le_bytes());
        h.update(t.height.to_le_bytes());
        hash_debug(&mut h, &(t.wrap_s, t.wrap_t, t.filter));
        hash_f32s(&mut h, t.texels.iter().flat_map(|p| p.to_array()));
        hash_debug(&mut h, &t.procedural);
    }
    h.update(b"\0materials");
    for m in &scene.materials {
        // Debug prints floats in shortest round-trip form: equal text, equal values.
        hash_debug(&mut h, m);
    }
    h.update(b"\0objects");
    for o in &scene.objects {
        hash_debug(&mut h, &(&o.shape, &o.transform, o.material));
    }
    h.update(b"\0lights");
    for l in &scene.lights {
        match l {
            LightDesc::Environment {
                path,
                scale,
                transform,
                mapping,
                ..
            } => {
                hash_debug(&mut h, &(scale, transform, mapping));
                hash_file(&mut h, path)?;
            }
            other => hash_debug(&mut h, other),
        }
    }
    h.update(b"\0cameras");
    for c in &scene.cameras {
        hash_debug(
            &mut h,
            &(
                &c.name,
                &c.camera_to_world,
                c.vfov_deg,
                c.aspect,
                c.aperture_radius,
                c.focus_distance,
                c.projection,
            ),
        );
    }
    h.update(b"\0env");
    if let Some(env) = env {
        hash_file(&mut h, env)?;
    }
    Ok(h.finalize().iter().map(|b| format!("{b:02x}")).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn digest_follows_content_not_names() {
        let a = super::super::builtin::load("cornell").unwrap();
        let mut b = a.clone();
        b.name = "renamed".into();
        b.source = Some("/elsewhere/cornell.glb".into());
        let da = digest("cornell", &a, None).unwrap();
        assert_eq!(da, digest("cornell", &b, None).unwrap());
        assert_eq!(da.len(), 64);
        let mut c = a.clone();
        c.objects[0].transform.w_axis.x += 1e-6;
        assert_ne!(da, digest("cornell", &c, None).unwrap());
        let mut d = a.clone();
        d.materials[0].base_color.x *= 0.5;
        assert_ne!(da, digest("cornell", &d, None).unwrap());
    }
}

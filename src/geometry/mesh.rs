//! The shading attributes of a triangle mesh, shared by the flat meshes of the world
//! (`primitive::GeometryStore`) and the object-space copies of instanced meshes (`instance`).

use crate::math::{Vec2, Vec3, Vec4};

/// Shading attributes of a triangle mesh: world space for a flat mesh, object space for an
/// instanced one.
#[derive(Clone, Debug, Default)]
pub struct MeshAttributes {
    pub indices: Vec<[u32; 3]>,
    pub normals: Option<Vec<Vec3>>,
    pub tangents: Option<Vec<Vec4>>,
    pub uv0: Option<Vec<Vec2>>,
    pub uv1: Option<Vec<Vec2>>,
    pub colors: Option<Vec<Vec4>>,
    pub material: u32,
}

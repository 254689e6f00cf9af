//! FBX node transforms and the file's axis/unit system.
//!
//! The local transform of a node is (FBX SDK, "Computing transformation matrix"):
//!
//! `L = T · Roff · Rp · Rpre · R · Rpost⁻¹ · Rp⁻¹ · Soff · Sp · S · Sp⁻¹`
//!
//! with T = `Lcl Translation`, R = `Lcl Rotation` composed in `RotationOrder`, Rpre/Rpost the
//! pre- and post-rotations (always XYZ), Roff/Rp the rotation offset and pivot, Soff/Sp the scaling
//! offset and pivot and S = `Lcl Scaling`. The geometric transform (`Geometric*`) applies to the
//! node's own geometry only, not to its children.

use super::props::Props;
use glam::{DMat3, DMat4, DVec3};

/// Euler rotation orders of `RotationOrder`; "XYZ" rotates about X first.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RotationOrder {
    Xyz,
    Xzy,
    Yzx,
    Yxz,
    Zxy,
    Zyx,
}

impl RotationOrder {
    /// The order of the enum value, and whether it was understood (6, spheric XYZ, is not).
    pub fn from_fbx(v: i64) -> (RotationOrder, bool) {
        match v {
            0 => (RotationOrder::Xyz, true),
            1 => (RotationOrder::Xzy, true),
            2 => (RotationOrder::Yzx, true),
            3 => (RotationOrder::Yxz, true),
            4 => (RotationOrder::Zxy, true),
            5 => (RotationOrder::Zyx, true),
            _ => (RotationOrder::Xyz, false),
        }
    }
}

/// The rotation matrix of Euler angles in degrees, applied in `order` (first letter first).
pub fn euler(deg: DVec3, order: RotationOrder) -> DMat4 {
    let x = DMat4::from_rotation_x(deg.x.to_radians());
    let y = DMat4::from_rotation_y(deg.y.to_radians());
    let z = DMat4::from_rotation_z(deg.z.to_radians());
    // Column vectors: the first rotation applied is the rightmost factor.
    match order {
        RotationOrder::Xyz => z * y * x,
        RotationOrder::Xzy => y * z * x,
        RotationOrder::Yzx => x * z * y,
        RotationOrder::Yxz => z * x * y,
        RotationOrder::Zxy => y * x * z,
        RotationOrder::Zyx => x * y * z,
    }
}

/// How a node inherits its parent's transform (`InheritType`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Inherit {
    /// eInheritRrSs: parent rotation and scale are applied before the child's rotation.
    RrSs,
    /// eInheritRSrs: the ordinary `parent · local` (the default).
    RSrs,
    /// eInheritRrs: the parent's own local scaling is not inherited (Maya's segment scale
    /// compensation).
    Rrs,
}

/// A node's local transform and what its children need to know about it.
pub struct LocalTransform {
    pub matrix: DMat4,
    pub scaling: DVec3,
    pub inherit: Inherit,
    pub geometric: DMat4,
    /// Things that were approximated, for warnings.
    pub notes: Vec<String>,
}

pub fn local_transform(p: &Props) -> LocalTransform {
    let mut notes = Vec::new();
    let zero = DVec3::ZERO;
    let one = DVec3::ONE;
    let t = p.vec3("Lcl Translation", zero);
    let r = p.vec3("Lcl Rotation", zero);
    let s = p.vec3("Lcl Scaling", one);
    let (order, known) = RotationOrder::from_fbx(p.int("RotationOrder", 0));
    if !known {
        notes.push("uses the spheric XYZ rotation order, read as XYZ".to_string());
    }
    let pre = p.vec3("PreRotation", zero);
    let post = p.vec3("PostRotation", zero);
    let roff = p.vec3("RotationOffset", zero);
    let rp = p.vec3("RotationPivot", zero);
    let soff = p.vec3("ScalingOffset", zero);
    let sp = p.vec3("ScalingPivot", zero);
    let tr = DMat4::from_translation;
    let matrix = tr(t)
        * tr(roff)
        * tr(rp)
        * euler(pre, RotationOrder::Xyz)
        * euler(r, order)
        * euler(post, RotationOrder::Xyz).inverse()
        * tr(-rp)
        * tr(soff)
        * tr(sp)
        * DMat4::from_scale(s)
        * tr(-sp);
    let inherit = match p.int("InheritType", 1) {
        0 => Inherit::RrSs,
        2 => Inherit::Rrs,
        _ => Inherit::RSrs,
    };
    let geometric = tr(p.vec3("GeometricTranslation", zero))
        * euler(p.vec3("GeometricRotation", zero), RotationOrder::Xyz)
        * DMat4::from_scale(p.vec3("GeometricScaling", one));
    LocalTransform {
        matrix,
        scaling: s,
        inherit,
        geometric,
        notes,
    }
}

/// Composes a child's global transform from its parent's.
pub fn compose(parent_global: DMat4, parent_scaling: DVec3, child: &LocalTransform) -> DMat4 {
    match child.inherit {
        Inherit::RSrs => parent_global * child.matrix,
        Inherit::Rrs => {
            // The parent's local scale is undone before the child is applied.
            let inv = DVec3::new(
                safe_recip(parent_scaling.x),
                safe_recip(parent_scaling.y),
                safe_recip(parent_scaling.z),
            );
            parent_global * DMat4::from_scale(inv) * child.matrix
        }
        // Approximated as RSrs: exact only when scales are uniform, which is how exporters use
        // it; the caller warns.
        Inherit::RrSs => parent_global * child.matrix,
    }
}

fn safe_recip(v: f64) -> f64 {
    if v.abs() > 1e-12 { 1.0 / v } else { 1.0 }
}

/// The file's axis system and unit (`GlobalSettings`), as the matrix that takes file coordinates
/// to Trayecto's: metres, +Y up, right-handed with the camera's default view down −Z (glTF's).
pub struct AxisSystem {
    pub matrix: DMat4,
    pub unit_scale_cm: f64,
    pub notes: Vec<String>,
}

pub fn axis_system(p: &Props) -> AxisSystem {
    let mut notes = Vec::new();
    let up = p.int("UpAxis", 1);
    let up_sign = p.int("UpAxisSign", 1);
    let front = p.int("FrontAxis", 2);
    let front_sign = p.int("FrontAxisSign", 1);
    let coord = p.int("CoordAxis", 0);
    let coord_sign = p.int("CoordAxisSign", 1);
    let valid = [up, front, coord].iter().all(|a| (0..3).contains(a))
        && up != front
        && up != coord
        && front != coord
        && [up_sign, front_sign, coord_sign]
            .iter()
            .all(|s| *s == 1 || *s == -1);
    let (axes, signs) = if valid {
        ([coord, up, front], [coord_sign, up_sign, front_sign])
    } else {
        notes.push(format!(
            "GlobalSettings has an invalid axis system (up {up}·{up_sign}, front {front}·{front_sign}, \
             coord {coord}·{coord_sign}); assuming +Y up"
        ));
        ([0, 1, 2], [1, 1, 1])
    };
    // Row i of the rotation picks the file axis that becomes Trayecto's axis i: the coord (right)
    // axis becomes +X, up becomes +Y and the front axis +Z.
    let mut rows = [DVec3::ZERO; 3];
    for i in 0..3 {
        let mut r = DVec3::ZERO;
        r[axes[i] as usize] = signs[i] as f64;
        rows[i] = r;
    }
    let rot = DMat3::from_cols(rows[0], rows[1], rows[2]).transpose();
    let mut unit = p.number("UnitScaleFactor", 1.0);
    if !(unit > 0.0) || !unit.is_finite() {
        notes.push(format!(
            "GlobalSettings UnitScaleFactor {unit} is not a positive number; assuming centimetres"
        ));
        unit = 1.0;
    }
    // UnitScaleFactor is the number of centimetres per file unit.
    let matrix = DMat4::from_mat3(rot) * DMat4::from_scale(DVec3::splat(unit / 100.0));
    AxisSystem {
        matrix,
        unit_scale_cm: unit,
        notes,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn euler_orders_apply_first_letter_first() {
        // Rotating +X by 90° about Z then 90° about X: Z takes X to Y, X then takes Y to Z.
        let m = euler(DVec3::new(90.0, 0.0, 90.0), RotationOrder::Zxy);
        let v = m.transform_vector3(DVec3::X);
        assert!((v - DVec3::Z).length() < 1e-12, "{v}");
        // XYZ order: X first (X is unchanged), then Z takes it to Y.
        let m = euler(DVec3::new(90.0, 0.0, 90.0), RotationOrder::Xyz);
        let v = m.transform_vector3(DVec3::X);
        assert!((v - DVec3::Y).length() < 1e-12, "{v}");
    }

    #[test]
    fn pivots_rotate_about_the_pivot() {
        use super::super::binary::Property;
        use super::super::props::PropValue;
        use super::super::props::PropertyTable;
        let mut t = PropertyTable::default();
        let v3 = |x: f64, y: f64, z: f64| PropValue {
            values: vec![Property::F64(x), Property::F64(y), Property::F64(z)],
        };
        t.entries.insert("Lcl Rotation".into(), v3(0.0, 0.0, 90.0));
        t.entries.insert("RotationPivot".into(), v3(1.0, 0.0, 0.0));
        let p = Props {
            own: &t,
            template: None,
        };
        let l = local_transform(&p);
        // The pivot itself stays put; the origin swings around it to (1, -1, 0).
        assert!((l.matrix.transform_point3(DVec3::X) - DVec3::X).length() < 1e-12);
        let o = l.matrix.transform_point3(DVec3::ZERO);
        assert!((o - DVec3::new(1.0, -1.0, 0.0)).length() < 1e-12, "{o}");
    }

    #[test]
    fn z_up_files_are_rotated_to_y_up() {
        use super::super::binary::Property;
        use super::super::props::{PropValue, PropertyTable};
        let mut t = PropertyTable::default();
        let int = |v: i32| PropValue {
            values: vec![Property::I32(v)],
        };
        // 3ds Max / Blender Z-up: up Z, front −Y, coord X.
        t.entries.insert("UpAxis".into(), int(2));
        t.entries.insert("FrontAxis".into(), int(1));
        t.entries.insert("FrontAxisSign".into(), int(-1));
        t.entries.insert(
            "UnitScaleFactor".into(),
            PropValue {
                values: vec![Property::F64(100.0)],
            },
        );
        let a = axis_system(&Props {
            own: &t,
            template: None,
        });
        // File +Z (up) becomes +Y; file metres stay metres.
        let up = a.matrix.transform_vector3(DVec3::Z);
        assert!((up - DVec3::Y).length() < 1e-12, "{up}");
        let fwd = a.matrix.transform_vector3(DVec3::Y);
        assert!((fwd - DVec3::NEG_Z).length() < 1e-12, "{fwd}");
        assert!((a.matrix.determinant() - 1.0).abs() < 1e-12);
    }
}

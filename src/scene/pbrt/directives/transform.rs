//! Transform directives: `Identity`, `Translate`, `Scale`, `Rotate`, `LookAt`, `Transform`,
//! `ConcatTransform`, named coordinate systems, `ActiveTransform` and `TransformTimes` (pbrt-v4
//! file format, "Transformations"). Shapes and the camera whose start and end transforms differ
//! move between the two `TransformTimes` (scene::animation::MovingTransform).

use crate::math::{Mat4, Vec3};
use crate::scene::SceneError;
use crate::scene::pbrt::{Active, Cursor, Loader, look_at};

impl Loader {
    fn transform_directive(&mut self, m: Mat4, set: bool) {
        // Transform directives change the transforms `ActiveTransform` selects.
        let apply = |cur: Mat4| if set { m } else { cur * m };
        if self.gs.active != Active::End {
            self.gs.ctm = apply(self.gs.ctm);
        }
        if self.gs.active != Active::Start {
            self.gs.ctm_end = apply(self.gs.ctm_end);
        }
    }

    pub(super) fn transform_directives(
        &mut self,
        name: &str,
        p: &mut Cursor,
        at: &str,
    ) -> Result<bool, SceneError> {
        match name {
            "Identity" => self.transform_directive(Mat4::IDENTITY, true),
            "Translate" => {
                let v = p.numbers(3, at)?;
                self.transform_directive(
                    Mat4::from_translation(Vec3::new(v[0], v[1], v[2])),
                    false,
                );
            }
            "Scale" => {
                let v = p.numbers(3, at)?;
                self.transform_directive(Mat4::from_scale(Vec3::new(v[0], v[1], v[2])), false);
            }
            "Rotate" => {
                let v = p.numbers(4, at)?;
                let axis = Vec3::new(v[1], v[2], v[3]);
                if axis.length_squared() == 0.0 {
                    return Err(SceneError::invalid(at, "Rotate: the axis is zero"));
                }
                self.transform_directive(
                    Mat4::from_axis_angle(axis.normalize(), v[0].to_radians()),
                    false,
                );
            }
            "LookAt" => {
                let v = p.numbers(9, at)?;
                let m = look_at(
                    Vec3::new(v[0], v[1], v[2]),
                    Vec3::new(v[3], v[4], v[5]),
                    Vec3::new(v[6], v[7], v[8]),
                )
                .map_err(|e| SceneError::invalid(at, format!("LookAt: {e}")))?;
                self.transform_directive(m, false);
            }
            "Transform" | "ConcatTransform" => {
                let v = p.matrix(at)?;
                // pbrt lists the matrix column by column (it transposes the row-major array).
                let m = Mat4::from_cols_array(&v);
                if !crate::math::mat4_is_finite(&m) {
                    return Err(SceneError::invalid(
                        at,
                        format!("{name}: non-finite matrix"),
                    ));
                }
                self.transform_directive(m, name == "Transform");
            }
            "CoordinateSystem" => {
                let n = p.string(at)?;
                self.named_coord.insert(n, self.gs.ctm);
            }
            "CoordSysTransform" => {
                let n = p.string(at)?;
                match self.named_coord.get(&n) {
                    Some(m) => {
                        let m = *m;
                        self.gs.ctm = m;
                        self.gs.ctm_end = m;
                    }
                    None => self.warn(format!(
                        "{at}: CoordSysTransform: no coordinate system named '{n}'"
                    )),
                }
            }
            "ActiveTransform" => {
                let w = p.word(at)?;
                self.gs.active = match w.as_str() {
                    "StartTime" => Active::Start,
                    "EndTime" => Active::End,
                    "All" => Active::All,
                    other => {
                        return Err(SceneError::invalid(
                            at,
                            format!(
                                "ActiveTransform: unknown '{other}' (StartTime, EndTime or All)"
                            ),
                        ));
                    }
                };
            }
            "TransformTimes" => {
                let v = p.numbers(2, at)?;
                let (t0, t1) = (v[0] as f64, v[1] as f64);
                if !(t0.is_finite() && t1.is_finite() && t0 <= t1) {
                    return Err(SceneError::invalid(
                        at,
                        format!("TransformTimes {t0} {t1}: the start must not be after the end"),
                    ));
                }
                self.transform_times = [t0, t1];
            }
            _ => return Ok(false),
        }
        Ok(true)
    }
}

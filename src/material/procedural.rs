//! pbrt-v4 procedural textures evaluated at each hit: `constant`, `scale`, `mix`,
//! `directionmix`, `checkerboard` (2D and 3D), `bilerp` and `imagemap` nodes inside them, with
//! pbrt-v4's 2D mappings (`uv`, `spherical`, `cylindrical`, `planar`) and its 3D point mapping.
//!
//! A [`Procedural`] is a flat arena of plain-data [`TexExpr`] nodes, children always before their
//! parents and the root last, so evaluation is a recursive `match` over indices that cannot cycle,
//! allocates nothing and has no trait objects. It lives in the scene's texture table (a
//! [`Texture`] whose `procedural` is set), so a material refers to it with an ordinary
//! [`super::TextureRef`] and [`super::eval::sample_texture`] is the one place that tells the two
//! kinds apart.
//!
//! **Filtering.** pbrt-v4's checkerboard is antialiased in closed form: the ±1 square wave in each
//! coordinate is convolved with a triangle filter of half-width 1.5 × the larger screen-space
//! derivative of that coordinate (PBRT 4th ed. §10.5.2 "Checkerboard", `Checkerboard()`); image
//! nodes read the MIP pyramid with the mapped derivatives. Trayecto follows its own
//! `--texture-filter` switch: the hit's uv derivatives ([`crate::geometry::SurfaceHit::duv`]) are
//! non-zero only with `--texture-filter trilinear` on triangle hits, and with zero derivatives the
//! filtered checkerboard is exactly the point-sampled one (pbrt's own formula takes that branch).
//! Mappings from the hit point (`spherical`, `cylindrical`, `planar`, 3D checkerboards) are always
//! point-sampled: the hit keeps uv derivatives, not the point's screen-space derivatives.

use super::Texture;
use crate::math::{Mat4, Vec2, Vec3, Vec4};

/// Most nodes one procedural texture may hold.
pub const MAX_NODES: usize = 4096;
/// Deepest chain of nested nodes (bounds the evaluator's recursion).
pub const MAX_DEPTH: u32 = 64;
/// Most node evaluations one lookup may cost when shared sub-graphs are counted each time they
/// are reached (a chain of `scale` textures each naming the previous twice doubles per level).
pub const MAX_COST: u64 = 4096;

/// Where a 2D node reads its texture coordinates (pbrt-v4 `TextureMapping2D`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Mapping2D {
    /// (s, t) = (su·u + du, sv·v + dv), pbrt's (u, v) with v up.
    Uv { su: f32, sv: f32, du: f32, dv: f32 },
    /// (θ/π, φ/2π) of the hit point in texture space (pbrt-v4 `SphericalMapping`).
    Spherical { texture_from_world: Mat4 },
    /// ((π + atan2(y, x))/2π, z) of the point in texture space (`CylindricalMapping`).
    Cylindrical { texture_from_world: Mat4 },
    /// (ds + p·vs, dt + p·vt) of the point in texture space (`PlanarMapping`).
    Planar {
        texture_from_world: Mat4,
        vs: Vec3,
        vt: Vec3,
        ds: f32,
        dt: f32,
    },
}

/// One node of a procedural texture. Children are indices of earlier nodes of the same arena.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TexExpr {
    Const(Vec3),
    /// `scene.textures[texture]` (an image) at the mapped (s, 1 − t), × `scale`, optionally
    /// inverted to max(0, 1 − value) (pbrt-v4 `SpectrumImageTexture`).
    Image {
        texture: u32,
        scale: f32,
        invert: bool,
        map: Mapping2D,
    },
    /// `tex[0]` where ⌊s⌋ + ⌊t⌋ is even, `tex[1]` where it is odd.
    Checkerboard {
        tex: [u32; 2],
        map: Mapping2D,
    },
    /// `tex[0]` where ⌊x⌋ + ⌊y⌋ + ⌊z⌋ of the texture-space point is even, `tex[1]` where odd.
    Checkerboard3D {
        tex: [u32; 2],
        texture_from_world: Mat4,
    },
    /// `tex` × the first channel of `scale`.
    Scale {
        tex: u32,
        scale: u32,
    },
    /// (1 − a)·tex[0] + a·tex[1], a the first channel of `amount`.
    Mix {
        tex: [u32; 2],
        amount: u32,
    },
    /// a·tex[0] + (1 − a)·tex[1] with a = |n·dir|, n the geometric normal, `dir` in world space.
    DirectionMix {
        tex: [u32; 2],
        dir: Vec3,
    },
    /// Bilinear interpolation of v00, v10, v01, v11 at the mapped (s, t), not wrapped.
    Bilerp {
        v: [Vec3; 4],
        map: Mapping2D,
    },
}

impl TexExpr {
    /// Indices of the node's children: the first `.1` entries of `.0`.
    pub fn children(&self) -> ([u32; 3], usize) {
        match *self {
            TexExpr::Const(_) | TexExpr::Image { .. } | TexExpr::Bilerp { .. } => ([0; 3], 0),
            TexExpr::Checkerboard { tex, .. }
            | TexExpr::Checkerboard3D { tex, .. }
            | TexExpr::DirectionMix { tex, .. } => ([tex[0], tex[1], 0], 2),
            TexExpr::Scale { tex, scale } => ([tex, scale, 0], 2),
            TexExpr::Mix { tex, amount } => ([tex[0], tex[1], amount], 3),
        }
    }
}

/// What a texture node sees of a hit, in pbrt's conventions.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TexCtx {
    /// pbrt's (u, v): v grows up the image (Trayecto stores 1 − v).
    pub uv: Vec2,
    /// (∂u/∂x, ∂v/∂x, ∂u/∂y, ∂v/∂y) per pixel in pbrt's (u, v); zero for a point sample.
    pub duv: Vec4,
    /// World-space hit point.
    pub p: Vec3,
    /// Geometric normal.
    pub n: Vec3,
}

/// A procedural texture: nodes in evaluation order, the root last.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Procedural {
    pub nodes: Vec<TexExpr>,
}

impl Procedural {
    /// Checks the arena: not empty, within [`MAX_NODES`], every child before its parent (so
    /// there is no cycle), depth within [`MAX_DEPTH`], cost within [`MAX_COST`], finite
    /// parameters, and image nodes naming images (non-procedural entries) of `textures`.
    pub fn validate(&self, textures: &[Texture]) -> Result<(), String> {
        if self.nodes.is_empty() || self.nodes.len() > MAX_NODES {
            return Err(format!(
                "procedural texture has {} nodes (1..={MAX_NODES} allowed)",
                self.nodes.len()
            ));
        }
        let mut depth = vec![0u32; self.nodes.len()];
        let mut cost = vec![0u64; self.nodes.len()];
        for (i, n) in self.nodes.iter().enumerate() {
            let (c, k) = n.children();
            let (mut d, mut s) = (1u32, 1u64);
            for &ch in &c[..k] {
                let ch = ch as usize;
                if ch >= i {
                    return Err(format!(
                        "procedural texture node {i} refers to node {ch}, not an earlier one"
                    ));
                }
                d = d.max(depth[ch] + 1);
                s = s.saturating_add(cost[ch]);
            }
            if d > MAX_DEPTH || s > MAX_COST {
                return Err(format!(
                    "procedural texture is nested {d} deep and costs {s} node evaluations per \
                     lookup (limits {MAX_DEPTH} and {MAX_COST})"
                ));
            }
            (depth[i], cost[i]) = (d, s);
            if !n.is_finite() {
                return Err(format!(
                    "procedural texture node {i} has a non-finite parameter"
                ));
            }
            if let TexExpr::Image { texture, .. } = n {
                match textures.get(*texture as usize) {
                    Some(t) if t.procedural.is_none() => {}
                    _ => {
                        return Err(format!(
                            "procedural texture node {i} names texture {texture}, which is not an image"
                        ));
                    }
                }
            }
        }
        Ok(())
    }

    /// Adds `offset` to the texture index of every image node (when the scene holding this
    /// texture is appended after `offset` other textures).
    pub fn shift_images(&mut self, offset: u32) {
        for n in &mut self.nodes {
            if let TexExpr::Image { texture, .. } = n {
                *texture = texture.saturating_add(offset);
            }
        }
    }

    /// The texture's value at `ctx`.
    #[inline]
    pub fn eval(&self, textures: &[Texture], ctx: &TexCtx) -> Vec3 {
        match self.nodes.len() {
            0 => Vec3::ZERO,
            n => Graph(&self.nodes).node(textures, ctx, n as u32 - 1),
        }
    }
}

/// Node `root` of an arena whose children precede their parents (the pbrt loader evaluates its
/// whole texture graph this way before it splits it into [`Procedural`]s).
pub fn eval_node(nodes: &[TexExpr], root: u32, textures: &[Texture], ctx: &TexCtx) -> Vec3 {
    Graph(nodes).node(textures, ctx, root)
}

/// An arena being evaluated.
struct Graph<'a>(&'a [TexExpr]);

impl Graph<'_> {
    fn node(&self, textures: &[Texture], ctx: &TexCtx, i: u32) -> Vec3 {
        // `validate` guarantees children precede parents; `get` keeps a scene built in code
        // without validation from panicking.
        let Some(n) = self.0.get(i as usize) else {
            return Vec3::ZERO;
        };
        match *n {
            TexExpr::Const(c) => c,
            TexExpr::Image {
                texture,
                scale,
                invert,
                map,
            } => {
                let Some(tex) = textures.get(texture as usize) else {
                    return Vec3::ZERO;
                };
                let (st, d) = map.map(ctx);
                // Images have v = 0 at the top: pbrt looks up (s, 1 − t). The derivatives'
                // signs do not matter to the MIP level.
                let c = tex
                    .lookup_filtered(Vec2::new(st.x, 1.0 - st.y), d)
                    .truncate()
                    * scale;
                if invert {
                    (Vec3::ONE - c).max(Vec3::ZERO)
                } else {
                    c
                }
            }
            TexExpr::Checkerboard { tex, map } => {
                let (st, d) = map.map(ctx);
                // pbrt-v4: the filter half-width is 1.5 × the larger derivative per axis.
                let ds = 1.5 * d.x.abs().max(d.z.abs());
                let dt = 1.5 * d.y.abs().max(d.w.abs());
                let w = 0.5 - 0.5 * square_wave(st.x, ds) * square_wave(st.y, dt);
                self.blend(textures, ctx, tex, w as f32)
            }
            TexExpr::Checkerboard3D {
                tex,
                texture_from_world,
            } => {
                let p = texture_from_world.transform_point3(ctx.p);
                let w = 0.5
                    - 0.5 * square_wave(p.x, 0.0) * square_wave(p.y, 0.0) * square_wave(p.z, 0.0);
                self.blend(textures, ctx, tex, w as f32)
            }
            TexExpr::Scale { tex, scale } => {
                let s = self.node(textures, ctx, scale).x;
                if s == 0.0 {
                    Vec3::ZERO
                } else {
                    self.node(textures, ctx, tex) * s
                }
            }
            TexExpr::Mix { tex, amount } => {
                let a = self.node(textures, ctx, amount).x;
                self.blend(textures, ctx, tex, a)
            }
            TexExpr::DirectionMix { tex, dir } => {
                let a = ctx.n.dot(dir).abs();
                self.blend(textures, ctx, tex, 1.0 - a)
            }
            TexExpr::Bilerp { v, map } => {
                let (st, _) = map.map(ctx);
                let (s, t) = (st.x, st.y);
                v[0] * ((1.0 - s) * (1.0 - t))
                    + v[1] * (s * (1.0 - t))
                    + v[2] * ((1.0 - s) * t)
                    + v[3] * (s * t)
            }
        }
    }

    /// (1 − w)·tex[0] + w·tex[1], evaluating only the children whose weight is not zero (as
    /// pbrt-v4 does: a checkerboard of two image textures reads one image per point sample).
    #[inline]
    fn blend(&self, textures: &[Texture], ctx: &TexCtx, tex: [u32; 2], w: f32) -> Vec3 {
        let a = if w != 1.0 {
            self.node(textures, ctx, tex[0]) * (1.0 - w)
        } else {
            Vec3::ZERO
        };
        let b = if w != 0.0 {
            self.node(textures, ctx, tex[1]) * w
        } else {
            Vec3::ZERO
        };
        a + b
    }
}

impl TexExpr {
    fn is_finite(&self) -> bool {
        let m = |m: &Mapping2D| match m {
            Mapping2D::Uv { su, sv, du, dv } => [su, sv, du, dv].iter().all(|x| x.is_finite()),
            Mapping2D::Spherical { texture_from_world }
            | Mapping2D::Cylindrical { texture_from_world } => texture_from_world.is_finite(),
            Mapping2D::Planar {
                texture_from_world,
                vs,
                vt,
                ds,
                dt,
            } => {
                texture_from_world.is_finite()
                    && vs.is_finite()
                    && vt.is_finite()
                    && ds.is_finite()
                    && dt.is_finite()
            }
        };
        match self {
            TexExpr::Const(c) => c.is_finite(),
            TexExpr::Image { scale, map, .. } => scale.is_finite() && m(map),
            TexExpr::Checkerboard { map, .. } => m(map),
            TexExpr::Checkerboard3D {
                texture_from_world, ..
            } => texture_from_world.is_finite(),
            TexExpr::Scale { .. } | TexExpr::Mix { .. } => true,
            TexExpr::DirectionMix { dir, .. } => dir.is_finite(),
            TexExpr::Bilerp { v, map } => v.iter().all(|c| c.is_finite()) && m(map),
        }
    }
}

impl Mapping2D {
    /// (s, t) and their derivatives (∂s/∂x, ∂t/∂x, ∂s/∂y, ∂t/∂y) at `ctx`. Mappings of the hit
    /// point have no derivatives here (see the module notes).
    #[inline]
    pub fn map(&self, ctx: &TexCtx) -> (Vec2, Vec4) {
        match *self {
            Mapping2D::Uv { su, sv, du, dv } => (
                Vec2::new(su * ctx.uv.x + du, sv * ctx.uv.y + dv),
                ctx.duv * Vec4::new(su, sv, su, sv),
            ),
            Mapping2D::Spherical { texture_from_world } => {
                let v = texture_from_world
                    .transform_point3(ctx.p)
                    .normalize_or_zero();
                let theta = v.z.clamp(-1.0, 1.0).acos();
                let mut phi = v.y.atan2(v.x);
                if phi < 0.0 {
                    phi += std::f32::consts::TAU;
                }
                (
                    Vec2::new(
                        theta * std::f32::consts::FRAC_1_PI,
                        phi / std::f32::consts::TAU,
                    ),
                    Vec4::ZERO,
                )
            }
            Mapping2D::Cylindrical { texture_from_world } => {
                let p = texture_from_world.transform_point3(ctx.p);
                (
                    Vec2::new(
                        (std::f32::consts::PI + p.y.atan2(p.x)) / std::f32::consts::TAU,
                        p.z,
                    ),
                    Vec4::ZERO,
                )
            }
            Mapping2D::Planar {
                texture_from_world,
                vs,
                vt,
                ds,
                dt,
            } => {
                let p = texture_from_world.transform_point3(ctx.p);
                (Vec2::new(ds + p.dot(vs), dt + p.dot(vt)), Vec4::ZERO)
            }
        }
    }
}

/// The ±1 square wave of period 2 (+1 on [2k, 2k + 1), −1 on [2k + 1, 2k + 2)) averaged with a
/// triangle filter of half-width `r` centred at `x` (PBRT 4th ed. §10.5.2, eq. 10.23 and the
/// filtered checkerboard that follows). With D(x) the second antiderivative of the wave,
/// D(x) = x/2 + y(1 − 2|y|), y = x/2 − ⌊x/2⌋ − ½, the triangle-filtered value is the second
/// difference (D(x + r) − 2D(x) + D(x − r))/r². Without a footprint (or inside one square) it is
/// the point value. Evaluated in f64: at x ≈ 10³ and r ≈ 10⁻², the second difference is below
/// f32 resolution.
#[inline]
fn square_wave(x: f32, r: f32) -> f64 {
    let (x, r) = (x as f64, r as f64);
    if !(r > 0.0) || (x - r).floor() == (x + r).floor() {
        // Saturating cast: a huge or NaN coordinate still gives ±1.
        return if (x.floor() as i64) & 1 == 0 {
            1.0
        } else {
            -1.0
        };
    }
    let d = |x: f64| {
        let y = x / 2.0 - (x / 2.0).floor() - 0.5;
        x / 2.0 + y * (1.0 - 2.0 * y.abs())
    };
    ((d(x + r) - 2.0 * d(x) + d(x - r)) / (r * r)).clamp(-1.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn uv(u: f32, v: f32) -> TexCtx {
        TexCtx {
            uv: Vec2::new(u, v),
            ..Default::default()
        }
    }

    fn checker(su: f32) -> Procedural {
        Procedural {
            nodes: vec![
                TexExpr::Const(Vec3::ONE),
                TexExpr::Const(Vec3::ZERO),
                TexExpr::Checkerboard {
                    tex: [0, 1],
                    map: Mapping2D::Uv {
                        su,
                        sv: su,
                        du: 0.0,
                        dv: 0.0,
                    },
                },
            ],
        }
    }

    /// Point samples alternate at every cell of a 2000-per-unit checkerboard: a 512² bake of it
    /// could not (it has fewer texels than cells).
    #[test]
    fn checkerboard_is_exact_at_high_frequency() {
        let c = checker(2000.0);
        for i in 0..4000 {
            let u = (i as f32 + 0.5) / 2000.0 * 0.25;
            let cell = (u * 2000.0).floor() as i64;
            let want = if cell % 2 == 0 { 1.0 } else { 0.0 };
            assert_eq!(c.eval(&[], &uv(u, 0.0001)).x, want, "u {u}");
        }
        // Negative coordinates: ⌊−0.3⌋ = −1 is odd.
        assert_eq!(checker(1.0).eval(&[], &uv(-0.3, 0.5)).x, 0.0);
        assert_eq!(checker(1.0).eval(&[], &uv(-0.3, -0.5)).x, 1.0);
    }

    /// The filtered checkerboard is the point value inside a cell, tends to ½ under a footprint
    /// of many cells, and its mean over a cell pair equals the box average (the filter keeps
    /// the mean).
    #[test]
    fn filtered_checkerboard_averages_over_the_footprint() {
        let c = checker(1.0);
        let mut ctx = uv(0.25, 0.25);
        ctx.duv = Vec4::new(0.01, 0.0, 0.0, 0.01);
        assert_eq!(c.eval(&[], &ctx).x, 1.0);
        ctx.duv = Vec4::new(7.3, 0.0, 0.0, 7.3);
        let wide = c.eval(&[], &ctx).x;
        assert!((wide - 0.5).abs() < 0.02, "{wide}");
        // Across the edge u = 1 with a footprint of 0.2 cells the value is between the two.
        let mut ctx = uv(1.0, 0.5);
        ctx.duv = Vec4::new(0.2, 0.0, 0.0, 0.0);
        let edge = c.eval(&[], &ctx).x;
        assert!((edge - 0.5).abs() < 1e-3, "{edge}");
        // Mean over many positions with a moderate footprint stays ½.
        let mut s = 0.0;
        for i in 0..1000 {
            let mut ctx = uv(i as f32 * 0.002 + 0.0007, 0.3);
            ctx.duv = Vec4::new(0.3, 0.0, 0.0, 0.0);
            s += c.eval(&[], &ctx).x;
        }
        assert!((s / 1000.0 - 0.5).abs() < 0.01, "{}", s / 1000.0);
    }

    #[test]
    fn checkerboard_3d_uses_the_texture_space_point() {
        let p = Procedural {
            nodes: vec![
                TexExpr::Const(Vec3::ONE),
                TexExpr::Const(Vec3::ZERO),
                TexExpr::Checkerboard3D {
                    tex: [0, 1],
                    // Texture space is world scaled by 4: cells of 1/4.
                    texture_from_world: Mat4::from_scale(Vec3::splat(4.0)),
                },
            ],
        };
        let at = |x: f32, y: f32, z: f32| {
            p.eval(
                &[],
                &TexCtx {
                    p: Vec3::new(x, y, z),
                    ..Default::default()
                },
            )
            .x
        };
        assert_eq!(at(0.1, 0.1, 0.1), 1.0);
        assert_eq!(at(0.3, 0.1, 0.1), 0.0);
        assert_eq!(at(0.3, 0.3, 0.1), 1.0);
        assert_eq!(at(0.3, 0.3, 0.3), 0.0);
        assert_eq!(at(-0.1, 0.1, 0.1), 0.0);
    }

    #[test]
    fn scale_mix_direction_mix_and_bilerp() {
        let p = Procedural {
            nodes: vec![
                TexExpr::Const(Vec3::new(1.0, 2.0, 4.0)),
                TexExpr::Const(Vec3::splat(0.25)),
                TexExpr::Scale { tex: 0, scale: 1 },
                TexExpr::Const(Vec3::ZERO),
                TexExpr::Mix {
                    tex: [2, 3],
                    amount: 1,
                },
            ],
        };
        // 0.75 × (0.25, 0.5, 1) + 0.25 × 0.
        assert_eq!(p.eval(&[], &uv(0.0, 0.0)), Vec3::new(0.1875, 0.375, 0.75));
        let d = Procedural {
            nodes: vec![
                TexExpr::Const(Vec3::ONE),
                TexExpr::Const(Vec3::ZERO),
                TexExpr::DirectionMix {
                    tex: [0, 1],
                    dir: Vec3::Y,
                },
            ],
        };
        let n = |n: Vec3| TexCtx {
            n,
            ..Default::default()
        };
        assert_eq!(d.eval(&[], &n(Vec3::Y)).x, 1.0);
        assert_eq!(d.eval(&[], &n(-Vec3::Y)).x, 1.0);
        assert_eq!(d.eval(&[], &n(Vec3::X)).x, 0.0);
        let b = Procedural {
            nodes: vec![TexExpr::Bilerp {
                v: [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z],
                map: Mapping2D::Uv {
                    su: 1.0,
                    sv: 1.0,
                    du: 0.0,
                    dv: 0.0,
                },
            }],
        };
        // v10 is the s = 1, t = 0 corner; outside [0, 1]² pbrt extrapolates.
        assert_eq!(b.eval(&[], &uv(1.0, 0.0)), Vec3::X);
        assert_eq!(b.eval(&[], &uv(0.0, 1.0)), Vec3::Y);
        assert_eq!(b.eval(&[], &uv(2.0, 0.0)), Vec3::X * 2.0);
    }

    #[test]
    fn spherical_cylindrical_planar_mappings() {
        let ctx = |p: Vec3| TexCtx {
            p,
            ..Default::default()
        };
        let s = Mapping2D::Spherical {
            texture_from_world: Mat4::IDENTITY,
        };
        let (st, _) = s.map(&ctx(Vec3::new(0.0, 2.0, 0.0)));
        assert!((st - Vec2::new(0.5, 0.25)).length() < 1e-6, "{st}");
        let c = Mapping2D::Cylindrical {
            texture_from_world: Mat4::from_translation(Vec3::new(0.0, 0.0, 1.0)),
        };
        let (st, _) = c.map(&ctx(Vec3::new(-1.0, 0.0, 0.5)));
        assert!((st - Vec2::new(1.0, 1.5)).length() < 1e-6, "{st}");
        let p = Mapping2D::Planar {
            texture_from_world: Mat4::IDENTITY,
            vs: Vec3::X,
            vt: Vec3::Z,
            ds: 0.5,
            dt: 0.0,
        };
        let (st, _) = p.map(&ctx(Vec3::new(1.0, 7.0, 2.0)));
        assert_eq!(st, Vec2::new(1.5, 2.0));
    }

    /// Cycles, forward references, depth and exponential sharing are refused.
    #[test]
    fn hostile_arenas_are_refused() {
        let forward = Procedural {
            nodes: vec![TexExpr::Scale { tex: 0, scale: 0 }],
        };
        assert!(forward.validate(&[]).is_err());
        assert!(Procedural::default().validate(&[]).is_err());
        // Each node scales the previous by itself: cost doubles per level.
        let mut nodes = vec![TexExpr::Const(Vec3::ONE)];
        for i in 0..20 {
            nodes.push(TexExpr::Scale { tex: i, scale: i });
        }
        let e = Procedural { nodes }.validate(&[]).unwrap_err();
        assert!(e.contains("costs"), "{e}");
        let mut nodes = vec![TexExpr::Const(Vec3::ONE)];
        for i in 0..100 {
            nodes.push(TexExpr::Mix {
                tex: [i, 0],
                amount: 0,
            });
        }
        assert!(Procedural { nodes }.validate(&[]).is_err());
        // An image node must name an image.
        let img = Procedural {
            nodes: vec![TexExpr::Image {
                texture: 3,
                scale: 1.0,
                invert: false,
                map: Mapping2D::Uv {
                    su: 1.0,
                    sv: 1.0,
                    du: 0.0,
                    dv: 0.0,
                },
            }],
        };
        assert!(img.validate(&[]).is_err());
        assert!(checker(3.0).validate(&[]).is_ok());
    }
}

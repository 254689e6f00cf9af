//! glTF materials and textures: the metallic-roughness inputs, texture references with their
//! coordinate sets and transforms, and the KHR material extensions Trayecto reads.

use super::*;

impl Loader<'_> {
    /// The scene texture for glTF texture `t` decoded as sRGB or linear.
    pub(super) fn texture(&mut self, t: &gltf::Texture, srgb: bool) -> Result<usize, SceneError> {
        if let Some(&i) = self.textures.get(&(t.index(), srgb)) {
            return Ok(i);
        }
        // Decoded ahead, in parallel (images.rs), from the source images.rs chooses.
        let image = self.texture_source(t)?;
        let mut tex = self.image_texture(image, srgb)?;
        let s = t.sampler();
        let wrap = |w: gltf::texture::WrappingMode| match w {
            gltf::texture::WrappingMode::ClampToEdge => WrapMode::ClampToEdge,
            gltf::texture::WrappingMode::MirroredRepeat => WrapMode::MirroredRepeat,
            gltf::texture::WrappingMode::Repeat => WrapMode::Repeat,
        };
        tex.wrap_s = wrap(s.wrap_s());
        tex.wrap_t = wrap(s.wrap_t());
        tex.filter = match s.mag_filter() {
            Some(gltf::texture::MagFilter::Nearest) => FilterMode::Nearest,
            _ => FilterMode::Bilinear,
        };
        // glTF sampler: a `minFilter` of NEAREST or LINEAR asks for no MIP maps; the
        // *_MIPMAP_* filters, or none given, allow the pyramid (`--texture-filter`).
        tex.mipmap = !matches!(
            s.min_filter(),
            Some(gltf::texture::MinFilter::Nearest | gltf::texture::MinFilter::Linear)
        );
        let missing = is_missing_texture(&tex);
        self.scene.textures.push(tex);
        let i = self.scene.textures.len() - 1;
        if missing {
            self.missing.insert(i);
        }
        self.textures.insert((t.index(), srgb), i);
        Ok(i)
    }

    pub(super) fn texcoord_set(&mut self, set: u32, what: &str) -> u32 {
        if set > 1 {
            self.warn_once(
                &format!("texcoord{set}"),
                format!(
                    "texture-coordinate set {set} ({what}) is not supported (only 0 and 1): set 0 is used"
                ),
            );
            0
        } else {
            set
        }
    }

    /// A texture reference from a `textureInfo`; `colour` textures are decoded as sRGB. Missing
    /// data textures are dropped (the factor alone applies); missing colour textures stay magenta.
    pub(super) fn tex_ref(
        &mut self,
        info: Option<gltf::texture::Info>,
        srgb: bool,
        keep_missing: bool,
        what: &str,
    ) -> Result<Option<TextureRef>, SceneError> {
        let Some(info) = info else { return Ok(None) };
        let texture = self.texture(&info.texture(), srgb)?;
        if self.missing.contains(&texture) && !keep_missing {
            return Ok(None);
        }
        let mut texcoord = info.tex_coord();
        let transform = info.texture_transform().map(|t| {
            if let Some(tc) = t.tex_coord() {
                texcoord = tc;
            }
            UvTransform {
                offset: Vec2::from(t.offset()),
                rotation: t.rotation(),
                scale: Vec2::from(t.scale()),
            }
        });
        let texcoord = self.texcoord_set(texcoord, what);
        Ok(Some(TextureRef {
            texture,
            texcoord,
            transform,
        }))
    }

    /// Normal and occlusion textures are not `textureInfo`s in the crate, so their
    /// KHR_texture_transform is read from the raw extension JSON.
    pub(super) fn special_tex_ref(
        &mut self,
        texture: gltf::Texture,
        tex_coord: u32,
        ext: Option<&gltf::json::Value>,
        what: &str,
    ) -> Result<Option<TextureRef>, SceneError> {
        self.special_tex_ref_as(texture, tex_coord, ext, what, false)
    }

    /// [`Loader::special_tex_ref`], decoded as sRGB when `srgb`.
    pub(super) fn special_tex_ref_as(
        &mut self,
        texture: gltf::Texture,
        tex_coord: u32,
        ext: Option<&gltf::json::Value>,
        what: &str,
        srgb: bool,
    ) -> Result<Option<TextureRef>, SceneError> {
        let index = self.texture(&texture, srgb)?;
        if self.missing.contains(&index) {
            return Ok(None);
        }
        let mut texcoord = tex_coord;
        let transform = ext.map(|v| {
            let pair = |key: &str, default: f32| -> Vec2 {
                v.get(key)
                    .and_then(|a| a.as_array())
                    .map(|a| {
                        Vec2::new(
                            a.first().and_then(|x| x.as_f64()).unwrap_or(default as f64) as f32,
                            a.get(1).and_then(|x| x.as_f64()).unwrap_or(default as f64) as f32,
                        )
                    })
                    .unwrap_or(Vec2::splat(default))
            };
            if let Some(tc) = v.get("texCoord").and_then(|x| x.as_u64()) {
                texcoord = tc.min(u32::MAX as u64) as u32;
            }
            UvTransform {
                offset: pair("offset", 0.0),
                rotation: v.get("rotation").and_then(|x| x.as_f64()).unwrap_or(0.0) as f32,
                scale: pair("scale", 1.0),
            }
        });
        let texcoord = self.texcoord_set(texcoord, what);
        Ok(Some(TextureRef {
            texture: index,
            texcoord,
            transform,
        }))
    }

    pub(super) fn material(&mut self, m: &gltf::Material) -> Result<Material, SceneError> {
        let name = m
            .name()
            .map(str::to_string)
            .unwrap_or_else(|| format!("material {}", m.index().unwrap_or(0)));
        let pbr = m.pbr_metallic_roughness();
        let bc = pbr.base_color_factor();
        let mut mat = Material {
            name: name.clone(),
            model: MaterialModel::metallic_roughness(),
            base_color: Vec3::new(bc[0], bc[1], bc[2]),
            alpha: bc[3],
            metallic: pbr.metallic_factor(),
            roughness: pbr.roughness_factor(),
            double_sided: m.double_sided(),
            alpha_cutoff: m.alpha_cutoff().unwrap_or(0.5),
            alpha_mode: match m.alpha_mode() {
                gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
                gltf::material::AlphaMode::Mask => AlphaMode::Mask,
                gltf::material::AlphaMode::Blend => AlphaMode::Blend,
            },
            ..Default::default()
        };
        mat.base_color_texture = self.tex_ref(pbr.base_color_texture(), true, true, "baseColor")?;
        mat.metallic_roughness_texture = self.tex_ref(
            pbr.metallic_roughness_texture(),
            false,
            false,
            "metallicRoughness",
        )?;
        if let Some(n) = m.normal_texture() {
            mat.normal_scale = n.scale();
            mat.normal_texture = self.special_tex_ref(
                n.texture(),
                n.tex_coord(),
                n.extension_value("KHR_texture_transform"),
                "normal",
            )?;
        }
        if let Some(o) = m.occlusion_texture() {
            mat.occlusion_strength = o.strength();
            mat.occlusion_texture = self.special_tex_ref(
                o.texture(),
                o.tex_coord(),
                o.extension_value("KHR_texture_transform"),
                "occlusion",
            )?;
        }
        // Emission is radiance: factor × KHR_materials_emissive_strength (docs/DESIGN.md §4).
        let strength = m.emissive_strength().unwrap_or(1.0);
        mat.emissive = Vec3::from(m.emissive_factor()) * strength;
        // The emissive texture only matters when the factor is non-zero (glTF multiplies them).
        if mat.emissive.max_element() > 0.0 {
            mat.emissive_texture = self.tex_ref(m.emissive_texture(), true, false, "emissive")?;
        } else if m.emissive_texture().is_some() {
            self.scene.warnings.push(format!(
                "material '{name}': emissive texture with a zero emissive factor emits nothing"
            ));
        }
        if let Some(t) = m.transmission() {
            mat.transmission = t.transmission_factor();
            mat.transmission_texture =
                self.tex_ref(t.transmission_texture(), false, false, "transmission")?;
        }
        if let Some(ior) = m.ior() {
            mat.ior = ior;
        }
        match m.volume() {
            Some(v) => {
                // thicknessFactor 0 means thin-walled (extension text). The thickness and its
                // texture are a rasteriser's estimate of the path length inside; a path tracer
                // uses the real one, so neither is needed (scene::volume).
                mat.thickness = v.thickness_factor();
                mat.thin_walled = mat.transmission > 0.0 && mat.thickness <= 0.0;
                mat.attenuation_color = Vec3::from(v.attenuation_color());
                mat.attenuation_distance = v.attenuation_distance();
            }
            None => mat.thin_walled = mat.transmission > 0.0,
        }
        if let Some(s) = m.specular() {
            mat.specular = s.specular_factor();
            mat.specular_color = Vec3::from(s.specular_color_factor());
            mat.specular_texture = self.tex_ref(s.specular_texture(), false, false, "specular")?;
            mat.specular_color_texture =
                self.tex_ref(s.specular_color_texture(), true, false, "specularColor")?;
        }
        if let Some(cc) = m.extension_value("KHR_materials_clearcoat") {
            self.clearcoat(&mut mat, cc)?;
        }
        self.bsdf_extensions(m, &mut mat)?;
        if m.unlit() {
            // KHR_materials_unlit: the base colour is shown as emitted radiance (docs/DESIGN.md §4).
            mat.model = MaterialModel::Unlit;
        }
        if m.pbr_specular_glossiness().is_some() {
            self.scene.warnings.push(format!(
                "material '{name}': KHR_materials_pbrSpecularGlossiness is not supported; the metallic-roughness fallback is used"
            ));
        }
        Ok(mat)
    }

    /// KHR_materials_clearcoat, read from the raw extension JSON (the `gltf` crate does not parse
    /// it): factors (default 0), the weight (R), roughness (G) and normal textures (all linear).
    pub(super) fn clearcoat(
        &mut self,
        mat: &mut Material,
        v: &gltf::json::Value,
    ) -> Result<(), SceneError> {
        let num = |key: &str, default: f32| -> Result<f32, SceneError> {
            match v.get(key) {
                None => Ok(default),
                Some(x) => x
                    .as_f64()
                    .map(|x| x as f32)
                    .filter(|x| x.is_finite() && (0.0..=1.0).contains(x))
                    .ok_or_else(|| {
                        SceneError::invalid(
                            self.label,
                            format!(
                                "material '{}': KHR_materials_clearcoat {key} must be a number in [0, 1]",
                                mat.name
                            ),
                        )
                    }),
            }
        };
        let mut x = *mat.metallic_roughness();
        x.clearcoat = num("clearcoatFactor", 0.0)?;
        x.clearcoat_roughness = num("clearcoatRoughnessFactor", 0.0)?;
        x.clearcoat_texture = self.raw_tex_ref(v.get("clearcoatTexture"), "clearcoat")?;
        x.clearcoat_roughness_texture =
            self.raw_tex_ref(v.get("clearcoatRoughnessTexture"), "clearcoatRoughness")?;
        if let Some(n) = v.get("clearcoatNormalTexture") {
            x.clearcoat_normal_scale = n
                .get("scale")
                .and_then(|x| x.as_f64())
                .map(|x| x as f32)
                .filter(|x| x.is_finite())
                .unwrap_or(1.0);
            x.clearcoat_normal_texture = self.raw_tex_ref(Some(n), "clearcoatNormal")?;
        }
        if let Some(m) = mat.metallic_roughness_mut() {
            *m = x;
        }
        Ok(())
    }

    /// A number of a material extension's JSON: `default` when absent; an error naming the
    /// material, extension and key when it is not a finite number in `range`.
    fn ext_num(
        &self,
        mat: &Material,
        v: &gltf::json::Value,
        ext: &str,
        key: &str,
        default: f32,
        range: std::ops::RangeInclusive<f32>,
    ) -> Result<f32, SceneError> {
        match v.get(key) {
            None => Ok(default),
            Some(x) => x
                .as_f64()
                .map(|x| x as f32)
                .filter(|x| x.is_finite() && range.contains(x))
                .ok_or_else(|| {
                    SceneError::invalid(
                        self.label,
                        format!(
                            "material '{}': {ext} {key} must be a number in [{}, {}]",
                            mat.name,
                            range.start(),
                            range.end()
                        ),
                    )
                }),
        }
    }

    /// A colour (3 numbers in `range`) of a material extension's JSON.
    fn ext_color(
        &self,
        mat: &Material,
        v: &gltf::json::Value,
        ext: &str,
        key: &str,
        default: Vec3,
    ) -> Result<Vec3, SceneError> {
        let Some(x) = v.get(key) else {
            return Ok(default);
        };
        let bad = || {
            SceneError::invalid(
                self.label,
                format!(
                    "material '{}': {ext} {key} must be three numbers in [0, 1]",
                    mat.name
                ),
            )
        };
        let a = x.as_array().filter(|a| a.len() == 3).ok_or_else(bad)?;
        let mut c = [0.0f32; 3];
        for (i, e) in a.iter().enumerate() {
            c[i] = e
                .as_f64()
                .map(|x| x as f32)
                .filter(|x| x.is_finite() && (0.0..=1.0).contains(x))
                .ok_or_else(bad)?;
        }
        Ok(Vec3::from(c))
    }

    /// The BSDF extensions read from the raw JSON (the `gltf` crate does not parse them):
    /// KHR_materials_sheen, _anisotropy, _iridescence, _dispersion and _diffuse_transmission,
    /// with their textures (colour textures sRGB, the others linear).
    fn bsdf_extensions(
        &mut self,
        m: &gltf::Material,
        mat: &mut Material,
    ) -> Result<(), SceneError> {
        const UNIT: std::ops::RangeInclusive<f32> = 0.0..=1.0;
        let mut x = *mat.metallic_roughness();
        if let Some(v) = m.extension_value("KHR_materials_sheen") {
            let e = "KHR_materials_sheen";
            x.sheen_color = self.ext_color(mat, v, e, "sheenColorFactor", Vec3::ZERO)?;
            x.sheen_roughness = self.ext_num(mat, v, e, "sheenRoughnessFactor", 0.0, UNIT)?;
            x.sheen_color_texture =
                self.raw_tex_ref_as(v.get("sheenColorTexture"), "sheenColor", true)?;
            x.sheen_roughness_texture =
                self.raw_tex_ref(v.get("sheenRoughnessTexture"), "sheenRoughness")?;
        }
        if let Some(v) = m.extension_value("KHR_materials_anisotropy") {
            let e = "KHR_materials_anisotropy";
            x.anisotropy = self.ext_num(mat, v, e, "anisotropyStrength", 0.0, UNIT)?;
            x.anisotropy_rotation =
                self.ext_num(mat, v, e, "anisotropyRotation", 0.0, -1.0e6..=1.0e6)?;
            x.anisotropy_texture = self.raw_tex_ref(v.get("anisotropyTexture"), "anisotropy")?;
        }
        if let Some(v) = m.extension_value("KHR_materials_iridescence") {
            let e = "KHR_materials_iridescence";
            x.iridescence = self.ext_num(mat, v, e, "iridescenceFactor", 0.0, UNIT)?;
            x.iridescence_ior = self.ext_num(mat, v, e, "iridescenceIor", 1.3, 1.0..=10.0)?;
            x.iridescence_thickness_min =
                self.ext_num(mat, v, e, "iridescenceThicknessMinimum", 100.0, 0.0..=1.0e5)?;
            x.iridescence_thickness_max =
                self.ext_num(mat, v, e, "iridescenceThicknessMaximum", 400.0, 0.0..=1.0e5)?;
            x.iridescence_texture = self.raw_tex_ref(v.get("iridescenceTexture"), "iridescence")?;
            x.iridescence_thickness_texture =
                self.raw_tex_ref(v.get("iridescenceThicknessTexture"), "iridescenceThickness")?;
        }
        if let Some(v) = m.extension_value("KHR_materials_dispersion") {
            x.dispersion = self.ext_num(
                mat,
                v,
                "KHR_materials_dispersion",
                "dispersion",
                0.0,
                0.0..=1.0e3,
            )?;
            if x.dispersion > 0.0 && (mat.transmission <= 0.0 || mat.thin_walled) {
                self.scene.warnings.push(format!(
                    "material '{}': KHR_materials_dispersion has no effect without volumetric transmission (KHR_materials_transmission with KHR_materials_volume thickness > 0)",
                    mat.name
                ));
            }
        }
        if let Some(v) = m.extension_value("KHR_materials_diffuse_transmission") {
            let e = "KHR_materials_diffuse_transmission";
            x.diffuse_transmission =
                self.ext_num(mat, v, e, "diffuseTransmissionFactor", 0.0, UNIT)?;
            x.diffuse_transmission_color =
                self.ext_color(mat, v, e, "diffuseTransmissionColorFactor", Vec3::ONE)?;
            x.diffuse_transmission_texture =
                self.raw_tex_ref(v.get("diffuseTransmissionTexture"), "diffuseTransmission")?;
            x.diffuse_transmission_color_texture = self.raw_tex_ref_as(
                v.get("diffuseTransmissionColorTexture"),
                "diffuseTransmissionColor",
                true,
            )?;
        }
        if let Some(m) = mat.metallic_roughness_mut() {
            *m = x;
        }
        // The transmissive component models clearcoat, sheen, anisotropy and iridescence too
        // (`material::bxdf::GltfTransmission`), so nothing here needs a warning.
        Ok(())
    }

    /// A `textureInfo` given as raw extension JSON (`index`, `texCoord`, KHR_texture_transform),
    /// decoded linearly. A missing or out-of-range index is an error naming the file.
    pub(super) fn raw_tex_ref(
        &mut self,
        info: Option<&gltf::json::Value>,
        what: &str,
    ) -> Result<Option<TextureRef>, SceneError> {
        self.raw_tex_ref_as(info, what, false)
    }

    /// [`Loader::raw_tex_ref`], decoded as sRGB when `srgb` (colour textures).
    pub(super) fn raw_tex_ref_as(
        &mut self,
        info: Option<&gltf::json::Value>,
        what: &str,
        srgb: bool,
    ) -> Result<Option<TextureRef>, SceneError> {
        let Some(info) = info else { return Ok(None) };
        let texture = info
            .get("index")
            .and_then(|i| i.as_u64())
            .and_then(|i| self.doc.textures().nth(i.min(usize::MAX as u64) as usize))
            .ok_or_else(|| {
                SceneError::invalid(
                    self.label,
                    format!("{what} texture: 'index' is missing or names no texture"),
                )
            })?;
        let tex_coord = info
            .get("texCoord")
            .and_then(|t| t.as_u64())
            .unwrap_or(0)
            .min(u32::MAX as u64) as u32;
        let transform = info
            .get("extensions")
            .and_then(|e| e.get("KHR_texture_transform"));
        self.special_tex_ref_as(texture, tex_coord, transform, what, srgb)
    }

    pub(super) fn default_material(&mut self) -> MaterialId {
        if let Some(m) = self.default_material {
            return m;
        }
        // The glTF default material: white, metallic 1, roughness 1.
        let m = Material {
            name: "glTF default".into(),
            model: MaterialModel::metallic_roughness(),
            base_color: Vec3::ONE,
            metallic: 1.0,
            roughness: 1.0,
            ..Default::default()
        };
        let id = self.scene.add_material(m);
        self.default_material = Some(id);
        id
    }

    // ---------------------------------------------------------------- binary data
}

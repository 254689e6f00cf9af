//! Binary data: buffer views and accessors (strides, sparse substitution, normalised integers),
//! decoded with checked arithmetic so a hostile file is an error, never a panic.

use super::*;

impl Loader<'_> {
    pub(super) fn view_bytes(&self, view: &gltf::buffer::View) -> Result<&[u8], SceneError> {
        if let Some(d) = self.decoded_view(view.index()) {
            return Ok(d);
        }
        let buf = self
            .buffers
            .get(view.buffer().index())
            .ok_or_else(|| self.err(format!("buffer view {} has no buffer", view.index())))?;
        let start = view.offset();
        let end = start.checked_add(view.length());
        end.and_then(|end| buf.get(start..end)).ok_or_else(|| {
            self.err(format!(
                "buffer view {} (bytes {}..+{}) lies outside its buffer of {} bytes",
                view.index(),
                start,
                view.length(),
                buf.len()
            ))
        })
    }

    /// Reads `count` elements of `ncomp` components each from a view at `offset`, as f32
    /// (normalised integers per glTF §3.11) or raw integer values.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn read_elements(
        &self,
        view: &gltf::buffer::View,
        offset: usize,
        count: usize,
        ty: DataType,
        ncomp: usize,
        normalized: bool,
        out: &mut Vec<[f64; 4]>,
        what: &str,
    ) -> Result<(), SceneError> {
        let data = self.view_bytes(view)?;
        let csize = ty.size();
        let esize = csize * ncomp;
        let stride = view.stride().unwrap_or(esize);
        if stride < esize {
            return Err(self.err(format!(
                "{what}: byte stride {stride} is smaller than an element ({esize} bytes)"
            )));
        }
        if count == 0 {
            return Ok(());
        }
        let needed = (count - 1)
            .checked_mul(stride)
            .and_then(|n| n.checked_add(esize))
            .and_then(|n| n.checked_add(offset));
        if needed.is_none_or(|n| n > data.len()) {
            return Err(self.err(format!(
                "{what}: {count} elements at offset {offset} with stride {stride} do not fit in buffer view {} ({} bytes)",
                view.index(),
                data.len()
            )));
        }
        out.reserve(count);
        for i in 0..count {
            let base = offset + i * stride;
            let mut e = [0.0f64; 4];
            for (c, v) in e.iter_mut().enumerate().take(ncomp) {
                let p = base + c * csize;
                *v = component(&data[p..p + csize], ty, normalized);
            }
            out.push(e);
        }
        Ok(())
    }

    /// Reads an accessor (with sparse substitution) as up to four f32 per element.
    pub(super) fn read_accessor(
        &self,
        acc: &gltf::Accessor,
        what: &str,
    ) -> Result<(Vec<[f64; 4]>, usize), SceneError> {
        let ncomp = match acc.dimensions() {
            Dimensions::Scalar => 1,
            Dimensions::Vec2 => 2,
            Dimensions::Vec3 => 3,
            Dimensions::Vec4 => 4,
            other => {
                return Err(self.err(format!(
                    "{what}: accessor {} has type {other:?}, expected a scalar or vector",
                    acc.index()
                )));
            }
        };
        let count = acc.count();
        if count > MAX_ACCESSOR_COUNT {
            return Err(self.err(format!(
                "{what}: accessor {} has an absurd element count ({count})",
                acc.index()
            )));
        }
        // Checked against the load's budget before allocating, with or without a buffer view
        // to back the count: a view-less accessor is zeros, `count` of them however small the
        // file (glTF 2.0 §3.6.2.4). The decoded elements are transient; the mesh keeps about
        // `ncomp` f32 per element.
        let elements = count as u64;
        let name = || format!("{what}: accessor {} ({count} elements)", acc.index());
        crate::limits::ensure_fits(elements * std::mem::size_of::<[f64; 4]>() as u64, name)
            .and_then(|_| crate::limits::charge(elements * ncomp as u64 * 4, name))
            .map_err(|e| self.err(e.to_string()))?;
        let ty = acc.data_type();
        let mut out = Vec::new();
        match acc.view() {
            Some(view) => self.read_elements(
                &view,
                acc.offset(),
                count,
                ty,
                ncomp,
                acc.normalized(),
                &mut out,
                what,
            )?,
            None => out.resize(count, [0.0; 4]),
        }
        if let Some(sparse) = acc.sparse() {
            let n = sparse.count();
            if n > count {
                return Err(self.err(format!(
                    "{what}: accessor {} has more sparse entries ({n}) than elements ({count})",
                    acc.index()
                )));
            }
            let idx = sparse.indices();
            let ity = match idx.index_type() {
                gltf::accessor::sparse::IndexType::U8 => DataType::U8,
                gltf::accessor::sparse::IndexType::U16 => DataType::U16,
                gltf::accessor::sparse::IndexType::U32 => DataType::U32,
            };
            let mut indices = Vec::new();
            self.read_elements(
                &idx.view(),
                idx.offset(),
                n,
                ity,
                1,
                false,
                &mut indices,
                what,
            )?;
            let vals = sparse.values();
            let mut values = Vec::new();
            self.read_elements(
                &vals.view(),
                vals.offset(),
                n,
                ty,
                ncomp,
                acc.normalized(),
                &mut values,
                what,
            )?;
            for (i, v) in indices.iter().zip(values) {
                let target = i[0] as usize;
                let slot = out.get_mut(target).ok_or_else(|| {
                    self.err(format!(
                        "{what}: sparse index {target} is out of range (count {count})"
                    ))
                })?;
                *slot = v;
            }
        }
        Ok((out, ncomp))
    }

    pub(super) fn read_indices(&self, acc: &gltf::Accessor) -> Result<Vec<u32>, SceneError> {
        if !matches!(
            acc.data_type(),
            DataType::U8 | DataType::U16 | DataType::U32
        ) || acc.dimensions() != Dimensions::Scalar
        {
            return Err(self.err(format!(
                "index accessor {} must hold unsigned integer scalars",
                acc.index()
            )));
        }
        let (v, _) = self.read_accessor(acc, "indices")?;
        Ok(v.iter().map(|e| e[0] as u32).collect())
    }

    // ---------------------------------------------------------------- meshes
}

/// One component, exactly (f64 holds every u32 index). Normalised integers follow glTF 2.0
/// §3.11 (signed: max(c / MAX, −1)).
fn component(b: &[u8], ty: DataType, normalized: bool) -> f64 {
    let at = |i: usize| b.get(i).copied().unwrap_or(0);
    let (v, max) = match ty {
        DataType::I8 => (at(0) as i8 as f64, 127.0),
        DataType::U8 => (at(0) as f64, 255.0),
        DataType::I16 => (i16::from_le_bytes([at(0), at(1)]) as f64, 32767.0),
        DataType::U16 => (u16::from_le_bytes([at(0), at(1)]) as f64, 65535.0),
        DataType::U32 => (
            u32::from_le_bytes([at(0), at(1), at(2), at(3)]) as f64,
            u32::MAX as f64,
        ),
        DataType::F32 => return f32::from_le_bytes([at(0), at(1), at(2), at(3)]) as f64,
    };
    if normalized { (v / max).max(-1.0) } else { v }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normalised_components() {
        assert_eq!(component(&[255], DataType::U8, true), 1.0);
        assert_eq!(component(&[0x80], DataType::I8, true), -1.0);
        assert_eq!(component(&[0xff, 0xff], DataType::U16, true), 1.0);
        assert_eq!(component(&[7, 0, 0, 0], DataType::U32, false), 7.0);
    }
}

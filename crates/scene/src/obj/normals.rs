//! The vertex normals of an OBJ's faces, for smooth surfaces (`crate::shading`): a face's own
//! `vn` where every corner names one, else its smoothing group's (`s N`: the area-weighted
//! mean of the group's face normals around each vertex), else none (flat).
//!
//! tobj makes up a normal index for a corner that names none (the previous corner's), so which
//! faces really name normals, and their smoothing groups (which tobj drops), are read from the
//! OBJ text, matched to tobj's faces one to one as the faces' lines are.

use std::collections::HashMap;

use glam::DVec3;

use super::{arities, Converter};
use base::error::Location;

/// The vertex normals smoothing groups give the faces of one OBJ group (see
/// [`Converter::smoothing_groups`]), in the scene's coordinates.
pub(super) struct Smoothed {
    sums: HashMap<(u32, u32), DVec3>,
}

impl Smoothed {
    /// The normals of a face of smoothing group `group` with vertex indices `idx`, in the
    /// order of [`Converter::corners`] (reversed under a mirroring transform).
    fn normals(&self, group: u32, idx: &[u32], mirrors: bool) -> Option<Vec<DVec3>> {
        let mut n: Vec<DVec3> = idx
            .iter()
            .map(|&i| self.sums.get(&(group, i)).copied())
            .collect::<Option<_>>()?;
        if mirrors {
            n.reverse();
        }
        Some(n)
    }
}

/// What an OBJ face says of its shading.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct FaceShading {
    /// Every corner names a vertex normal (`v//vn` or `v/vt/vn`). tobj makes up an index for a
    /// corner without one (the previous corner's), so only the text can tell.
    normals: bool,
    /// The smoothing group in force (`s N`); 0 for `s off`, `s 0` or none.
    group: u32,
}

/// [`FaceShading`] of every `f` or `l` statement of `text`, in order, if they match tobj's
/// faces one to one (as [`face_lines`]).
pub(super) fn face_shading(text: &str, models: &[tobj::Model]) -> Option<Vec<FaceShading>> {
    let mut group = 0u32;
    let mut out = Vec::new();
    for line in text.lines() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("s") => {
                group = match words.next() {
                    Some("off") | None => 0,
                    Some(w) => w.parse().unwrap_or(0),
                }
            }
            Some("f") => {
                let corners: Vec<&str> = words.collect();
                let normals = !corners.is_empty()
                    && corners
                        .iter()
                        .all(|c| c.split('/').nth(2).is_some_and(|n| !n.is_empty()));
                out.push(FaceShading { normals, group });
            }
            Some("l") => out.push(FaceShading {
                normals: false,
                group: 0,
            }),
            _ => {}
        }
    }
    let faces: usize = models.iter().map(|m| arities(&m.mesh).len()).sum();
    (faces == out.len()).then_some(out)
}

impl Converter<'_> {
    /// The shading of face `face_no` of the file, if the text's faces matched tobj's.
    pub(super) fn shading_of(&self, face_no: usize) -> Option<FaceShading> {
        self.face_shading.as_ref()?.get(face_no).copied()
    }

    /// The vertex normals of the smoothing groups of `model`'s faces that name no `vn`: per
    /// (group, vertex), the sum of the Newell normals (twice the area times the unit normal)
    /// of the group's faces around the vertex, so larger faces weigh more.
    pub(super) fn smoothing_groups(&self, model: &tobj::Model) -> Smoothed {
        let mesh = &model.mesh;
        let mut sums: HashMap<(u32, u32), DVec3> = HashMap::new();
        let mut start = 0usize;
        for (local, &arity) in arities(mesh).iter().enumerate() {
            let range = start..start + arity as usize;
            start += arity as usize;
            let Some(f) = self.shading_of(self.face_no + local) else {
                continue;
            };
            let Some(idx) = mesh.indices.get(range) else {
                continue;
            };
            if f.normals || f.group == 0 || idx.len() < 3 {
                continue;
            }
            // A face whose corners fail is reported by the pass that adds it.
            let Ok(corners) = self.corners(mesh, idx, &Location::file(self.obj_path)) else {
                continue;
            };
            let n = crate::newell_normal(&corners);
            for &i in idx {
                *sums.entry((f.group, i)).or_insert(DVec3::ZERO) += n;
            }
        }
        Smoothed { sums }
    }

    /// The normals of the face whose corners are at `range` of `mesh`'s index lists, shaded as
    /// `shading` says (see the module docs), in the order of [`Converter::corners`]; `None`
    /// for a flat face.
    pub(super) fn face_normals(
        &self,
        mesh: &tobj::Mesh,
        range: std::ops::Range<usize>,
        shading: Option<FaceShading>,
        smoothed: &Smoothed,
    ) -> Option<Vec<DVec3>> {
        match shading {
            Some(f) if f.normals => self.normals(mesh, range),
            Some(f) if f.group != 0 => {
                let idx = mesh.indices.get(range)?;
                smoothed.normals(f.group, idx, self.transform.mirrors())
            }
            _ => None,
        }
    }

    /// The transformed vertex normals (`vn`) of the face whose corners are at `range` of the
    /// mesh's index lists, in the order of [`Converter::corners`]; `None` when the face has none
    /// (or one is out of range: the face is then flat, as a face without `vn` is).
    fn normals(&self, mesh: &tobj::Mesh, range: std::ops::Range<usize>) -> Option<Vec<DVec3>> {
        let idx = mesh.normal_indices.get(range)?;
        let mut normals = Vec::with_capacity(idx.len());
        for &i in idx {
            let i = i as usize;
            let n = mesh.normals.get(3 * i..3 * i + 3)?;
            let n = DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64);
            normals.push(self.transform.normal(n));
        }
        if self.transform.mirrors() {
            normals.reverse();
        }
        Some(normals)
    }
}

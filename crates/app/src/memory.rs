//! Memory accounting: the bytes of every representation a method can hold, counted by one set of
//! rules that `stats`, `sweep`, the equal-error search and the docs all use.
//!
//! - **RRPs, stored** (what a solution file spends on them, and what the direct method is
//!   charged as storage): the trees as one split bit per node and the samples as three f32 per
//!   vertex ([`radiosity::file::samples_bytes`]); the derivatives are estimated again on load,
//!   by the same function a render after a solve uses. **Compact** (what the direct method
//!   holds): [`CompactStats::total_bytes`], the locate trees, leaf records and the vertices'
//!   Hermite data held as f32; **encoded** (measured, not stored: the Hermite data as 16-bit
//!   mantissas with 4-bit shifts of per-polygon scales): [`CompactStats::encoded_bytes`];
//!   **patch caches**: the direct method's caches of expanded patches, one per worker
//!   ([`CompactReconstruction::cache_bytes`] times the worker threads: what the frame's
//!   workspaces allocate), working memory reported beside the RRPs, not in them.
//! - **RRPs, expanded** (what the texture methods resample): one [`PatchCoeffs`] per leaf plus
//!   a 4-byte locate-tree node per node and a 4-byte root per polygon, computed from the compact
//!   form's counts without building it (the same formula as
//!   [`reconstruction::ReconstructionStats::bytes`]).
//! - **Textures**: [`TextureMemory`] at 8, 12 and 32 bits per channel, with and without mip
//!   chains; a texture method is charged [`texture_bytes`], 12 bits with chains (the paper's
//!   hardware counted 12-bit texels; mip-mapped drawing needs the chains).
//! - **Mesh**: [`reconstruction::mesh::MeshStats::bytes`] (vertices and indices).
//!
//! Invariant: [`Memory::method_bytes`] is the single answer to "what does this method store",
//! and it is what the sweep's `bytes` and the equal-error comparison report. What a method
//! holds in memory while it draws is counted apart, by [`working_bytes`]: the direct method's
//! compact RRPs plus its patch caches; a texture method's textures as f32 texels with their
//! chains (the 12-bit form is the paper's storage accounting, not what the CPU filters read);
//! the mesh's triangles as the renderer holds them (each a polygon record, its colour patch and
//! its primitive and bin records in a frame, `budget::MESH_TRIANGLE_BYTES`), not only its
//! vertices and indices.

use serde::Serialize;

use crate::prepare::Prepared;
use base::error::Result;
use base::method::Method;
use reconstruction::compact::{CompactReconstruction, CompactStats};
use reconstruction::texture::TextureMemory;
use reconstruction::PatchCoeffs;

/// The bytes a texture method is charged for a texture set: 12 bits per channel with mip chains.
pub fn texture_bytes(m: &TextureMemory) -> u64 {
    m.bytes_with_chain[1]
}

/// Bytes the direct method holds for `c`: the compact RRPs ([`CompactStats::total_bytes`]).
pub fn rrp_bytes(c: &CompactReconstruction) -> u64 {
    c.stats().total_bytes as u64
}

/// Bytes the RRPs of `p` are stored in: its solution's trees and samples
/// ([`radiosity::file::samples_bytes`]), from which every RRP is built.
pub fn rrp_stored_bytes(p: &Prepared) -> u64 {
    radiosity::file::samples_bytes(&p.solution)
}

/// Bytes of the direct method's patch caches for `c`: one per worker thread.
pub fn cache_bytes(c: &CompactReconstruction) -> u64 {
    (c.cache_bytes() * rayon::current_num_threads()) as u64
}

/// Bytes of the expanded RRPs of `c` (one patch per leaf, 4 B per locate-tree node and root).
pub fn expanded_rrp_bytes(c: &CompactReconstruction) -> u64 {
    let s = c.stats();
    (s.leaves * std::mem::size_of::<PatchCoeffs>() + 4 * s.nodes + 4 * s.polygons) as u64
}

/// Bytes `method` holds in memory while it draws (module docs): `textures` is the texture set
/// a texture method draws with (its memory), ignored by the other methods.
pub fn working_bytes(
    p: &Prepared,
    method: Method,
    textures: Option<&TextureMemory>,
) -> Result<u64> {
    Ok(match method {
        Method::Direct => rrp_bytes(&p.compact) + cache_bytes(&p.compact),
        Method::Texture(_) => {
            let m = match textures {
                Some(m) => *m,
                None => p.textures()?.0.memory,
            };
            m.bytes_with_chain[2]
        }
        Method::Mesh => p
            .mesh()?
            .0
            .stats
            .triangles
            .saturating_mul(crate::budget::MESH_TRIANGLE_BYTES),
        Method::Reference => 0,
    })
}

/// Every representation of one prepared scene.
#[derive(Debug, Clone, Serialize)]
pub struct Memory {
    /// RRPs as stored: the trees and samples they are built from ([`rrp_stored_bytes`]).
    pub rrp_stored: u64,
    /// Compact RRPs as held ([`CompactStats::total_bytes`]).
    pub rrp_compact: u64,
    /// Compact RRPs' Hermite data quantized ([`CompactStats::encoded_bytes`]; measured, not
    /// stored).
    pub rrp_encoded: u64,
    /// Expanded RRPs ([`expanded_rrp_bytes`]).
    pub rrp_expanded: u64,
    /// The direct method's patch caches, one per worker thread, all together.
    pub rrp_caches: u64,
    /// Textures under the job's size policy, at 8 / 12 / 32 bits, with and without mip chains.
    pub textures: TextureMemory,
    /// The Gouraud mesh's vertices and indices.
    pub mesh: u64,
}

impl Memory {
    /// The accounting of `p` (builds its textures and mesh if they are not built yet).
    pub fn of(p: &Prepared) -> Result<Memory> {
        let cs: CompactStats = p.compact.stats();
        Ok(Memory {
            rrp_stored: rrp_stored_bytes(p),
            rrp_compact: rrp_bytes(&p.compact),
            rrp_encoded: cs.encoded_bytes as u64,
            rrp_expanded: expanded_rrp_bytes(&p.compact),
            rrp_caches: cache_bytes(&p.compact),
            textures: p.textures()?.0.memory,
            mesh: p.mesh()?.0.stats.bytes,
        })
    }

    /// What `method` stores: the RRPs' trees and samples (direct), the 12-bit textures with
    /// chains (texture methods), the mesh, or nothing of its own (reference: the solution's
    /// oracle).
    pub fn method_bytes(&self, method: Method) -> u64 {
        match method {
            Method::Direct => self.rrp_stored,
            Method::Texture(_) => texture_bytes(&self.textures),
            Method::Mesh => self.mesh,
            Method::Reference => 0,
        }
    }
}

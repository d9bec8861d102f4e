//! The compact RRPs' Hermite form as bytes: [`CompactReconstruction::encode`] writes each
//! polygon's tree as one bit per node in canonical order, its scales, and the stored vertices'
//! shifts and mantissas; [`CompactReconstruction::decode`] accepts only that canonical form, so
//! `encode(decode(b)) == b` for every `b` it accepts, and returns an error, never a panic, on
//! anything else (docs/compact-rrps.md, Encoding). A solution file does not store it (it stores
//! the samples the RRPs are built from, 2.5-3x fewer bytes); `stats` reports its size, for a
//! reader that wants patches without running the estimator.

use super::*;

impl CompactReconstruction {
    /// Length of [`Self::encode`]'s output, without encoding.
    pub fn encoded_len(&self) -> usize {
        let mut n = MAGIC.len() + 4 + RECORD_BYTES * self.stored_vertices;
        for p in 0..self.roots.len() {
            n += 4 + self.polygon_nodes(p).len().div_ceil(8) + SCALE_BYTES;
        }
        n
    }

    /// The little-endian encoding described in the module docs.
    pub fn encode(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(self.encoded_len());
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&(self.roots.len() as u32).to_le_bytes());
        for p in 0..self.roots.len() {
            let nodes = self.polygon_nodes(p);
            out.extend_from_slice(&(nodes.len() as u32).to_le_bytes());
            for chunk in nodes.chunks(8) {
                let byte = chunk
                    .iter()
                    .enumerate()
                    .fold(0u8, |b, (k, &e)| b | (u8::from(e & LEAF == 0) << k));
                out.push(byte);
            }
            for s in self.scales[p] {
                out.extend_from_slice(&s.to_le_bytes());
            }
            for (m, s) in self.stored_integers(p) {
                for pair in s.chunks(2) {
                    out.push(pair[0] | pair[1] << 4);
                }
                for x in m {
                    out.extend_from_slice(&x.to_le_bytes());
                }
            }
        }
        debug_assert_eq!(out.len(), self.encoded_len());
        out
    }

    /// Decodes [`Self::encode`]'s output. Anything but the canonical form (module docs,
    /// Encoding) is an [`Error::Inconsistent`], never a panic.
    pub fn decode(bytes: &[u8]) -> Result<CompactReconstruction> {
        let mut r = Reader { bytes, at: 0 };
        if r.take(MAGIC.len())? != MAGIC {
            return Err(bad("not a compact reconstruction (wrong magic)"));
        }
        let count = r.u32()? as usize;
        // Each polygon takes at least 4 + 1 + 96 bytes: bound the count before allocating.
        if count > MAX_POLYGONS || count > r.left() / (5 + SCALE_BYTES) {
            return Err(bad("polygon count larger than the data"));
        }
        let mut out = CompactReconstruction::empty();
        for index in 0..count {
            let part = decode_part(&mut r)?;
            part.check(index)
                .map_err(|_| bad("a patch coefficient overflows f32"))?;
            out.push(part)?;
        }
        if r.left() != 0 {
            return Err(bad("trailing bytes"));
        }
        out.content_id = out.content_hash();
        Ok(out)
    }
}

fn bad(msg: &str) -> Error {
    Error::Inconsistent(format!("compact reconstruction decode: {msg}"))
}

struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn left(&self) -> usize {
        self.bytes.len() - self.at
    }

    fn take(&mut self, n: usize) -> Result<&'a [u8]> {
        if n > self.left() {
            return Err(bad("truncated"));
        }
        let s = &self.bytes[self.at..self.at + n];
        self.at += n;
        Ok(s)
    }

    fn u32(&mut self) -> Result<u32> {
        let b = self.take(4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }
}

/// The tree of one polygon from its node count and split bits.
fn decode_tree(r: &mut Reader) -> Result<Quadtree> {
    let n = r.u32()? as usize;
    if n % 4 != 1 || n.div_ceil(8) > r.left() {
        return Err(bad(
            "node count is not that of a quadtree or exceeds the data",
        ));
    }
    let bits = r.take(n.div_ceil(8))?;
    let tree = Quadtree::from_split_bits(n, bits)
        .ok_or_else(|| bad("split bits do not describe a quadtree of depth <= 16"))?;
    Ok(tree)
}

fn decode_part(r: &mut Reader) -> Result<Part> {
    let tree = decode_tree(r)?;
    let b = r.take(SCALE_BYTES)?;
    let scales: [f64; QUANTITIES] =
        std::array::from_fn(|q| f64::from_le_bytes(std::array::from_fn(|k| b[8 * q + k])));
    if scales
        .iter()
        .any(|s| !s.is_finite() || s.is_sign_negative())
    {
        return Err(bad("a scale is negative, -0 or not finite"));
    }
    let layout = Layout::of(&tree);
    let stored = layout.stored();
    if stored > r.left() / RECORD_BYTES {
        return Err(bad("truncated"));
    }
    let mut held = Vec::with_capacity(stored);
    for _ in 0..stored {
        let rec = r.take(RECORD_BYTES)?;
        let shift = |q: usize| rec[q / 2] >> (4 * (q % 2)) & 15;
        let at = QUANTITIES / 2;
        let mantissa = |q: usize| i16::from_le_bytes([rec[at + 2 * q], rec[at + 2 * q + 1]]);
        let mut h = [0.0f32; QUANTITIES];
        for (q, x) in h.iter_mut().enumerate() {
            let (m, s) = (mantissa(q), shift(q));
            if !canonical(m, s, scales[q]) {
                return Err(bad(
                    "a stored quantity is not in canonical form or overflows f32",
                ));
            }
            *x = held_value(m, s, scales[q]);
        }
        held.push(h);
    }
    Part::assemble(tree, layout, scales, held).map_err(bad)
}

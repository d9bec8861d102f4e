//! The bytes of a glTF file: the GLB container checked before the `gltf` crate splits it, the
//! document validated (with the extensions this loader reads), buffers read from the GLB's
//! binary chunk, from files beside the glTF or from `data:` URIs, and accessors read from them.
//!
//! Every length, offset and index of the file is checked, with checked arithmetic, before a
//! byte is read: a file that lies about its sizes is an input error naming the file and the
//! glTF key, never a panic or an allocation the file's own size does not bound (an accessor's
//! elements must lie in its buffer, so a read is at most as large as the files read).

use crate::checks::Cx;
use base::error::{Error, Location, Result};
use glam::DVec3;
use gltf::accessor::{DataType, Dimensions};
use std::path::{Path, PathBuf};

/// The GLB header: magic, version, total length (12 bytes).
const GLB_HEADER: usize = 12;

/// The required extensions whose data this loader may ignore: they change how materials and
/// textures look, or add lights, never where the geometry is. Any other required extension (mesh
/// compression, quantized positions) is refused: its primitives would be read wrongly.
const IGNORABLE_PREFIXES: &[&str] = &[
    "KHR_materials_",
    "KHR_texture_",
    "EXT_texture_",
    "KHR_lights_punctual",
];

/// A parsed and validated glTF file, and where its buffers come from.
pub(super) struct Opened {
    pub(super) gltf: ::gltf::Gltf,
    /// The file, for messages and relative buffer URIs.
    pub(super) path: PathBuf,
}

/// Parses the glTF file `bytes` (JSON or GLB) read from `path` and validates it: an input error
/// names the file and the key of the first problem.
pub(super) fn open(bytes: &[u8], path: &Path) -> Result<Opened> {
    let at = |key: &str, msg: String| Error::input(Location::file(path).with_key(key), msg);
    if bytes.starts_with(b"glTF") {
        check_glb_header(bytes).map_err(|m| Error::input(Location::file(path), m))?;
    }
    let gltf = ::gltf::Gltf::from_slice_without_validation(bytes).map_err(|e| match e {
        ::gltf::Error::Binary(b) => Error::input(Location::file(path), glb_problem(&b)),
        ::gltf::Error::Deserialize(j) => {
            let what = if bytes.starts_with(b"glTF") {
                "its JSON chunk"
            } else {
                "the file"
            };
            let mut loc = Location::file(path);
            if j.line() > 0 && !bytes.starts_with(b"glTF") {
                loc = loc.at_line(j.line());
            }
            Error::input(loc, format!("{what} is not glTF 2.0 JSON: {j}"))
        }
        e => Error::input(Location::file(path), format!("cannot be read as glTF: {e}")),
    })?;
    validate(&gltf, &at)?;
    Ok(Opened {
        gltf,
        path: path.to_path_buf(),
    })
}

/// Checks the 12-byte GLB header: version 2 and a length that the file holds (the `gltf` crate
/// would subtract the header from a shorter length).
fn check_glb_header(bytes: &[u8]) -> std::result::Result<(), String> {
    let word = |i: usize| {
        bytes
            .get(i..i + 4)
            .and_then(|b| b.try_into().ok())
            .map(u32::from_le_bytes)
    };
    let (Some(version), Some(length)) = (word(4), word(8)) else {
        return Err(format!(
            "is a truncated GLB: {} bytes, shorter than the 12-byte header",
            bytes.len()
        ));
    };
    if version != 2 {
        return Err(format!(
            "is a GLB of version {version}; only glTF 2.0 is read"
        ));
    }
    let length = length as usize;
    if length < GLB_HEADER + 8 {
        return Err(format!(
            "is a damaged GLB: its header gives a length of {length} bytes, less than a header \
             and a chunk header"
        ));
    }
    if length > bytes.len() {
        return Err(format!(
            "is a truncated GLB: its header gives {length} bytes, the file holds {}",
            bytes.len()
        ));
    }
    Ok(())
}

/// What the `gltf` crate's GLB error means, for a person.
fn glb_problem(e: &::gltf::binary::Error) -> String {
    use ::gltf::binary::Error as B;
    match e {
        B::Length {
            length,
            length_read,
        } => format!(
            "is a truncated GLB: it declares {length} bytes after its header, {length_read} follow"
        ),
        B::ChunkLength {
            ty,
            length,
            length_read,
        } => format!(
            "is a truncated GLB: its {ty:?} chunk declares {length} bytes, {length_read} follow"
        ),
        B::ChunkType(ty) => format!("is a damaged GLB: a {ty:?} chunk where another is expected"),
        B::UnknownChunkType(t) => format!("is a damaged GLB: unknown chunk type {t:?}"),
        B::Magic(m) => format!("is not a GLB (magic {m:?})"),
        B::Version(v) => format!("is a GLB of version {v}; only glTF 2.0 is read"),
        B::Io(e) => format!("is a truncated GLB: it ends inside a chunk header ({e})"),
    }
}

/// Validates the document: every index in range, every enumeration known. A required extension
/// this loader does not read is refused unless it only changes appearance (see
/// [`IGNORABLE_PREFIXES`]).
fn validate(gltf: &::gltf::Gltf, at: &dyn Fn(&str, String) -> Error) -> Result<()> {
    use ::gltf::json::validation::Validate;
    let root = gltf.document.as_json();
    for (i, ext) in root.extensions_required.iter().enumerate() {
        if !IGNORABLE_PREFIXES.iter().any(|p| ext.starts_with(p)) {
            return Err(at(
                &format!("extensionsRequired[{i}]"),
                format!(
                    "`{ext}` is required and not read (this loader reads uncompressed float \
                     positions): export without it (Blender: turn off Compression)"
                ),
            ));
        }
    }
    // gltf-json's own check of a primitive's POSITION bounds indexes the accessors before
    // their indices are known to be in range (it panics on an index past the end), so
    // attribute indices are checked here first.
    let accessors = root.accessors.len();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            for (semantic, index) in &prim.attributes {
                if index.value() >= accessors {
                    let name = match semantic {
                        ::gltf::json::validation::Checked::Valid(s) => s.to_string(),
                        ::gltf::json::validation::Checked::Invalid => "?".to_string(),
                    };
                    return Err(at(
                        &format!("meshes[{m}].primitives[{p}].attributes.{name}"),
                        format!(
                            "accessor {} does not exist (the file has {accessors}; the file is \
                             not valid glTF 2.0)",
                            index.value()
                        ),
                    ));
                }
            }
        }
    }
    let mut first: Option<(String, String)> = None;
    root.validate(root, ::gltf::json::Path::new, &mut |path, error| {
        use ::gltf::json::validation::Error as V;
        let key = path().to_string();
        // An appearance extension required (checked above), and the bounds glTF asks of
        // every POSITION accessor, which this loader does not use (it reads the positions).
        let ignorable = (key.starts_with("extensionsRequired") && matches!(error, V::Unsupported))
            || ((key.ends_with(".min") || key.ends_with(".max")) && matches!(error, V::Missing));
        if first.is_none() && !ignorable {
            first = Some((key, error.to_string()));
        }
    });
    match first {
        Some((key, error)) => Err(at(
            &key,
            format!("{error} (the file is not valid glTF 2.0)"),
        )),
        None => Ok(()),
    }
}

/// The buffers of one glTF file, each read once, when first needed.
pub(super) struct Buffers {
    /// The data of each buffer, once read (its first `byteLength` bytes).
    loaded: Vec<Option<Vec<u8>>>,
}

impl Buffers {
    pub(super) fn new(count: usize) -> Buffers {
        Buffers {
            loaded: (0..count).map(|_| None).collect(),
        }
    }

    /// The bytes of buffer `index`, read on first use: the GLB's binary chunk, a `data:` URI,
    /// or a file relative to the glTF's directory (recorded as an input of the scene).
    fn get(&mut self, cx: &mut Cx<'_>, file: &Opened, index: usize) -> Result<&[u8]> {
        let key = format!("buffers[{index}]");
        let Some(slot) = self.loaded.get_mut(index) else {
            return Err(Error::input(
                Location::file(&file.path).with_key(key),
                "is out of range",
            ));
        };
        if slot.is_none() {
            *slot = Some(read_buffer(cx, file, index)?);
        }
        Ok(slot.as_deref().unwrap_or(&[]))
    }
}

/// Reads buffer `index` of `file` whole, cut to its `byteLength`.
fn read_buffer(cx: &mut Cx<'_>, file: &Opened, index: usize) -> Result<Vec<u8>> {
    let key = format!("buffers[{index}]");
    let loc = |k: &str| Location::file(&file.path).with_key(k.to_string());
    let Some(buffer) = file.gltf.document.buffers().nth(index) else {
        return Err(Error::input(loc(&key), "is out of range"));
    };
    let (mut data, source) = match buffer.source() {
        ::gltf::buffer::Source::Bin => match &file.gltf.blob {
            Some(b) => (b.clone(), "the GLB's binary chunk".to_string()),
            None => {
                return Err(Error::input(
                    loc(&key),
                    "has no `uri`, so it is the GLB's binary chunk, and the file has none",
                ))
            }
        },
        ::gltf::buffer::Source::Uri(uri) => {
            let uri_key = format!("{key}.uri");
            read_uri(cx, &file.path, uri).map_err(|m| Error::input(loc(&uri_key), m))?
        }
    };
    let want = buffer.length();
    if data.len() < want {
        return Err(Error::input(
            loc(&format!("{key}.byteLength")),
            format!(
                "is {want} bytes, and {source} holds {} (the buffer is truncated)",
                data.len()
            ),
        ));
    }
    data.truncate(want);
    Ok(data)
}

/// The bytes a buffer's `uri` names, and what it is for messages: a `data:` URI decoded, or the
/// file at the (percent-decoded) relative path, read through the loader's reader.
fn read_uri(
    cx: &mut Cx<'_>,
    gltf_path: &Path,
    uri: &str,
) -> std::result::Result<(Vec<u8>, String), String> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let Some((header, payload)) = rest.split_once(',') else {
            return Err("is a data URI without a `,` before its data".to_string());
        };
        if !header.ends_with(";base64") {
            return Err(format!(
                "is a data URI that is not base64 (`data:{header},...`); only base64 data URIs \
                 are read"
            ));
        }
        let bytes = decode_base64(payload).map_err(|m| format!("is a data URI whose {m}"))?;
        return Ok((bytes, "its data URI".to_string()));
    }
    let scheme = uri.split_once(':').map(|(s, _)| s);
    if scheme.is_some_and(|s| s.len() > 1 && !s.contains('/')) {
        return Err(format!(
            "is `{uri}`; only file names relative to the glTF file and data: URIs are read"
        ));
    }
    let name = percent_decode(uri);
    let path = base::output::folder_of(gltf_path).join(&name);
    let bytes = (cx.read_bytes)(&path)
        .map_err(|e| format!("cannot read buffer file {}: {e}", path.display()))?;
    cx.inputs.push(path.clone());
    Ok((bytes, path.display().to_string()))
}

/// `uri` with its `%XX` escapes decoded (a URI's spaces are `%20`); `uri` itself if the result
/// is not UTF-8.
fn percent_decode(uri: &str) -> String {
    let b = uri.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex = b
            .get(i + 1..i + 3)
            .and_then(|h| std::str::from_utf8(h).ok())
            .and_then(|h| u8::from_str_radix(h, 16).ok());
        match (b[i], hex) {
            (b'%', Some(v)) => {
                out.push(v);
                i += 3;
            }
            (c, _) => {
                out.push(c);
                i += 1;
            }
        }
    }
    String::from_utf8(out).unwrap_or_else(|_| uri.to_string())
}

/// Decodes base64 (the standard or the URL-safe alphabet, `=` padding optional); the problem
/// otherwise, for a message.
pub(super) fn decode_base64(text: &str) -> std::result::Result<Vec<u8>, String> {
    let body = text.trim_end_matches('=');
    if text.len() - body.len() > 2 {
        return Err("base64 data has more than two `=` of padding".to_string());
    }
    let mut out = Vec::with_capacity(body.len() / 4 * 3 + 2);
    let (mut acc, mut bits) = (0u32, 0u32);
    for (i, c) in body.bytes().enumerate() {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' | b'-' => 62,
            b'/' | b'_' => 63,
            _ => {
                return Err(format!(
                    "base64 data has {:?} at character {i}, which base64 does not use",
                    char::from(c)
                ))
            }
        };
        acc = (acc << 6) | u32::from(v);
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    if body.len() % 4 == 1 {
        return Err("base64 data ends with a lone character (it is cut short)".to_string());
    }
    Ok(out)
}

/// Where the elements of one accessor lie: the bytes of its buffer, the first element's offset
/// and the step from one element to the next.
struct Span<'b> {
    bytes: &'b [u8],
    start: usize,
    stride: usize,
    count: usize,
}

impl Span<'_> {
    /// The `size` bytes of element `i` (in range by construction; empty otherwise).
    fn element(&self, i: usize, size: usize) -> &[u8] {
        let at = self.start + i * self.stride;
        self.bytes.get(at..at + size).unwrap_or(&[])
    }
}

/// The elements of accessor `accessor` (of `size` bytes each), checked to lie in its buffer
/// view and the view in its buffer. `key` is the glTF key that uses the accessor, for messages.
fn span<'b>(
    cx: &mut Cx<'_>,
    file: &Opened,
    buffers: &'b mut Buffers,
    accessor: &::gltf::Accessor<'_>,
    size: usize,
    key: &str,
) -> Result<Span<'b>> {
    let err = |msg: String| Error::input(Location::file(&file.path).with_key(key), msg);
    let a = accessor.index();
    if accessor.sparse().is_some() {
        return Err(err(format!(
            "accessors[{a}] is sparse; sparse accessors are not read (export without them)"
        )));
    }
    let Some(view) = accessor.view() else {
        return Err(err(format!(
            "accessors[{a}] has no bufferView (all its values would be zero)"
        )));
    };
    let v = view.index();
    let stride = view.stride().unwrap_or(size);
    if stride < size {
        return Err(err(format!(
            "bufferViews[{v}] has a byteStride of {stride}, less than the {size} bytes of one \
             element of accessors[{a}]"
        )));
    }
    let buffer = view.buffer();
    let b = buffer.index();
    let view_end = view.offset().checked_add(view.length());
    if view_end.is_none_or(|end| end > buffer.length()) {
        return Err(err(format!(
            "bufferViews[{v}] (bytes {} + {}) lies beyond the {} bytes of buffers[{b}]",
            view.offset(),
            view.length(),
            buffer.length()
        )));
    }
    let count = accessor.count();
    let needed = count
        .checked_sub(1)
        .map(|last| {
            last.checked_mul(stride)
                .and_then(|x| x.checked_add(size))
                .and_then(|x| x.checked_add(accessor.offset()))
        })
        .unwrap_or(Some(0));
    if needed.is_none_or(|n| n > view.length()) {
        return Err(err(format!(
            "accessors[{a}] ({count} elements of {size} bytes from byte {}, every {stride}) \
             reads beyond the {} bytes of bufferViews[{v}]",
            accessor.offset(),
            view.length()
        )));
    }
    let bytes = buffers.get(cx, file, b)?;
    Ok(Span {
        bytes,
        start: view.offset() + accessor.offset(),
        stride,
        count,
    })
}

/// The positions of a `POSITION` accessor (three floats each), every one finite, each
/// coordinate the `f64` nearest its shortest decimal (as an OBJ's).
pub(super) fn read_positions(
    cx: &mut Cx<'_>,
    file: &Opened,
    buffers: &mut Buffers,
    accessor: &::gltf::Accessor<'_>,
    key: &str,
) -> Result<Vec<DVec3>> {
    let err = |msg: String| Error::input(Location::file(&file.path).with_key(key), msg);
    let a = accessor.index();
    if accessor.dimensions() != Dimensions::Vec3 || accessor.data_type() != DataType::F32 {
        return Err(err(format!(
            "accessors[{a}] holds {:?} of {:?}; positions are read as VEC3 of FLOAT (quantized \
             positions are not read: export without quantization)",
            accessor.dimensions(),
            accessor.data_type()
        )));
    }
    let span = span(cx, file, buffers, accessor, 12, key)?;
    let mut out = Vec::with_capacity(span.count);
    for i in 0..span.count {
        let e = span.element(i, 12);
        let f = |k: usize| {
            e.get(4 * k..4 * k + 4)
                .and_then(|b| b.try_into().ok())
                .map_or(f32::NAN, f32::from_le_bytes)
        };
        let p = [f(0), f(1), f(2)];
        if !p.iter().all(|x| x.is_finite()) {
            return Err(err(format!(
                "element {i} of accessors[{a}] is {p:?}: positions must be finite"
            )));
        }
        out.push(super::super::obj::decimal3(p));
    }
    Ok(out)
}

/// The vertex indices of an `indices` accessor (unsigned bytes, shorts or ints), each checked to
/// be below `vertices`, the count of the primitive's positions.
pub(super) fn read_indices(
    cx: &mut Cx<'_>,
    file: &Opened,
    buffers: &mut Buffers,
    accessor: &::gltf::Accessor<'_>,
    vertices: usize,
    key: &str,
) -> Result<Vec<u32>> {
    let err = |msg: String| Error::input(Location::file(&file.path).with_key(key), msg);
    let a = accessor.index();
    let size = match (accessor.dimensions(), accessor.data_type()) {
        (Dimensions::Scalar, DataType::U8) => 1,
        (Dimensions::Scalar, DataType::U16) => 2,
        (Dimensions::Scalar, DataType::U32) => 4,
        (d, t) => {
            return Err(err(format!(
                "accessors[{a}] holds {d:?} of {t:?}; indices are SCALAR unsigned bytes, shorts \
                 or ints"
            )))
        }
    };
    let span = span(cx, file, buffers, accessor, size, key)?;
    let mut out = Vec::with_capacity(span.count);
    for i in 0..span.count {
        let e = span.element(i, size);
        let v = match *e {
            [b] => u32::from(b),
            [b0, b1] => u32::from(u16::from_le_bytes([b0, b1])),
            [b0, b1, b2, b3] => u32::from_le_bytes([b0, b1, b2, b3]),
            _ => u32::MAX,
        };
        if v as usize >= vertices {
            return Err(err(format!(
                "element {i} of accessors[{a}] is {v}, beyond the primitive's {vertices} \
                 positions"
            )));
        }
        out.push(v);
    }
    Ok(out)
}

/// The values of a FLOAT accessor of `n` components (SCALAR: 1, VEC2: 2), flattened, each
/// finite; `None` for an accessor of another shape (then it is not read).
pub(super) fn read_floats(
    cx: &mut Cx<'_>,
    file: &Opened,
    buffers: &mut Buffers,
    accessor: &::gltf::Accessor<'_>,
    n: usize,
    key: &str,
) -> Result<Option<Vec<f32>>> {
    let dims = match n {
        1 => Dimensions::Scalar,
        2 => Dimensions::Vec2,
        _ => Dimensions::Vec3,
    };
    if accessor.dimensions() != dims || accessor.data_type() != DataType::F32 {
        return Ok(None);
    }
    let span = span(cx, file, buffers, accessor, 4 * n, key)?;
    let mut out = Vec::with_capacity(span.count * n);
    for i in 0..span.count {
        let e = span.element(i, 4 * n);
        for k in 0..n {
            let x = e
                .get(4 * k..4 * k + 4)
                .and_then(|b| b.try_into().ok())
                .map_or(f32::NAN, f32::from_le_bytes);
            if !x.is_finite() {
                return Ok(None);
            }
            out.push(x);
        }
    }
    Ok(Some(out))
}

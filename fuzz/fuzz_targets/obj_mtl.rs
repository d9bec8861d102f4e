//! Fuzz target `obj_mtl`: the OBJ and MTL readers (tobj and the validation in
//! `crates/scene/src/obj.rs`).
//!
//! The input is `OBJ text` `0x00` `MTL text` (no `0x00`: no MTL file). A fixed scene includes
//! the OBJ as `fuzz.obj`, with a default material for faces without `usemtl` and a spot light,
//! so every valid OBJ loads; every MTL file the OBJ names (`mtllib`) reads as the MTL text.
//! Nothing touches the file system ([`scene::parse_scene_with`]).
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;


fn utf8(b: &[u8]) -> std::io::Result<String> {
    String::from_utf8(b.to_vec())
        .map_err(|_| std::io::Error::new(std::io::ErrorKind::InvalidData, "not UTF-8 text"))
}

fuzz_target!(|data: &[u8]| {
    let (obj, mtl) = match data.iter().position(|&b| b == 0) {
        Some(k) => (&data[..k], Some(&data[k + 1..])),
        None => (data, None),
    };
    let read = |p: &Path| -> std::io::Result<String> {
        if p.file_name().is_some_and(|n| n == "fuzz.obj") {
            utf8(obj)
        } else {
            match mtl {
                Some(m) => utf8(m),
                None => Err(std::io::ErrorKind::NotFound.into()),
            }
        }
    };
    let path = Path::new("fuzz-dir/fuzz.toml");
    match scene::parse_scene_with(&fixtures::hostile::obj_host_scene("fuzz.obj"), path, &read) {
        Ok(scene) => {
            let _ = app::report::summarize(&scene).to_string();
        }
        Err(e) => assert!(!e.to_string().is_empty()),
    }
});

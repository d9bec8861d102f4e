//! Fuzz target `scene`: the scene TOML loader.
//!
//! The input is the text of a scene file said to lie in the shipped `scenes/` directory, so the
//! shipped OBJ includes (`cornell-box/CornellBox-Original.obj`, `gallery/gallery.obj`) and their
//! MTL files load. Includes are read from a copy of `scenes/` held in memory: an input naming
//! any other file (`/dev/zero`, a FIFO) gets "not found" instead of touching the file system.
//! When a scene loads, the summary `check` prints is computed too.
#![no_main]

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;

/// Every file under the shipped `scenes/` directory, by path.
fn shipped() -> &'static BTreeMap<PathBuf, String> {
    static FILES: OnceLock<BTreeMap<PathBuf, String>> = OnceLock::new();
    FILES.get_or_init(|| {
        let mut files = BTreeMap::new();
        let mut dirs = vec![scenes_dir()];
        while let Some(d) = dirs.pop() {
            for e in std::fs::read_dir(&d)
                .expect("scenes/ is readable")
                .flatten()
            {
                let p = e.path();
                if p.is_dir() {
                    dirs.push(p);
                } else if let Ok(t) = std::fs::read_to_string(&p) {
                    files.insert(p, t);
                }
            }
        }
        files
    })
}

fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes")
}

fn read(path: &Path) -> std::io::Result<String> {
    shipped()
        .get(path)
        .cloned()
        .ok_or_else(|| std::io::Error::from(std::io::ErrorKind::NotFound))
}

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let path = scenes_dir().join("fuzz.toml");
    match scene::parse_scene_with(text, &path, &read) {
        Ok(scene) => {
            let _ = app::report::summarize(&scene).to_string();
        }
        Err(e) => assert!(!e.to_string().is_empty()),
    }
});

//! Fuzz target `solution`: the solution-file reader and the reconstruction `render` builds
//! from what it decodes.
//!
//! The first input byte chooses the scene the file is read against (its low bits index
//! [`SCENES`]) and, with its high bit set, repairs the envelope of the rest (format version, the
//! path and payload lengths, the scene hash, the checksum) so that mutations reach the payload
//! decoder instead of stopping at the checksum. The rest is the solution file's bytes.
//!
//! When the file decodes, the target does what `render` does with it: build the compact RRPs
//! from the samples (a file stores no RRPs), expand every patch, and round-trip them through
//! their own encoding (which `stats` measures). A file that decodes but is inconsistent must give
//! an `Err`, never a panic.
#![no_main]

use std::path::Path;
use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;
use radiosity::file;
use reconstruction::compact::CompactReconstruction;
use reconstruction::Estimator;
use scene::{load_scene, Scene};

/// The scenes a solution file is read against (fuzz/seed.sh solves the first two).
const SCENES: [&str; 4] = [
    "fuzz/tiny.toml",
    "scenes/two-spots.toml",
    "scenes/two-spots-narrow.toml",
    "scenes/cornell-box.toml",
];

fn scenes() -> &'static Vec<Scene> {
    static S: OnceLock<Vec<Scene>> = OnceLock::new();
    S.get_or_init(|| {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        SCENES
            .iter()
            .map(|s| load_scene(&root.join(s)).expect("the shipped scenes load"))
            .collect()
    })
}

fuzz_target!(|data: &[u8]| {
    let Some((&selector, rest)) = data.split_first() else {
        return;
    };
    let scenes = scenes();
    let scene = &scenes[(selector & 0x7f) as usize % scenes.len()];
    let mut bytes = rest.to_vec();
    if selector & 0x80 != 0 {
        file::reseal(&mut bytes, scene);
    }
    let solution = match file::decode(&bytes, scene) {
        Ok(d) => d,
        Err(file::Bad(_, message)) => {
            assert!(!message.is_empty());
            return;
        }
    };
    // What `jobs::prepare` does with a decoded file.
    let c = match CompactReconstruction::build(&solution.polygons, Estimator::default()) {
        Ok(c) => c,
        Err(e) => {
            assert!(!e.to_string().is_empty());
            return;
        }
    };
    assert_eq!(c.polygon_count(), scene.polygons.len());
    for id in 0..c.leaf_count() as u32 {
        let _ = c.expand(id);
    }
    for p in 0..c.polygon_count() as u32 {
        let _ = c.locate(p, 0.5, 0.5);
    }
    let encoded = c.encode();
    let back = CompactReconstruction::decode(&encoded).expect("an encoding decodes");
    assert_eq!(back.encode(), encoded);
});

//! A bare model as `check model.obj` loads it: the input is an OBJ and an MTL, split at the
//! first NUL byte, written as `m.obj` and `m.mtl` (the OBJ's `mtllib m.mtl` names it) in a
//! folder of this process, then loaded as a bare model and summarised as `check` does. Any
//! result is fine except a panic, an abort or an unbounded allocation (libFuzzer's
//! `-rss_limit_mb` and `-malloc_limit_mb` catch the last; the program caps each input read at
//! half its memory limit, set here to 256 MiB as `--memory-limit 512M` would).
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::PathBuf;
use std::sync::OnceLock;

fn folder() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let d = std::env::temp_dir().join(format!("pfs-fuzz-model-{}", std::process::id()));
        std::fs::create_dir_all(&d).expect("a scratch folder");
        d
    })
}

fuzz_target!(|data: &[u8]| {
    let (obj, mtl) = match data.iter().position(|&b| b == 0) {
        Some(i) => (&data[..i], &data[i + 1..]),
        None => (data, &[][..]),
    };
    let dir = folder();
    let (obj_path, mtl_path) = (dir.join("m.obj"), dir.join("m.mtl"));
    std::fs::write(&obj_path, obj).expect("writes the OBJ");
    std::fs::write(&mtl_path, mtl).expect("writes the MTL");
    if let Ok(scene) = scene::load_scene_with(
        &obj_path,
        &scene::LoadOptions {
            input_limit: 256 << 20,
            ..scene::LoadOptions::default()
        },
    ) {
        let _ = app::report::summarize(&scene);
    }
});

//! No input makes the loader panic: random and mutated scene, OBJ and MTL files load into a
//! scene that keeps every promise, or are refused as input errors.

use super::*;

/// Either a scene that keeps every promise, or an input error at `test.toml`.
fn loads_or_refuses(text: &str) {
    match parse_scene(text, Path::new("test.toml")) {
        Ok(s) => check_invariants(&s),
        Err(e) => {
            assert_eq!(e.exit_code(), EXIT_BAD_INPUT, "{e}");
            assert!(e.to_string().starts_with("test.toml"), "{e}");
        }
    }
}

/// Every number literal in `BASE`, as byte ranges.
fn number_spans(text: &str) -> Vec<(usize, usize)> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let starts =
            b[i].is_ascii_digit() || (b[i] == b'-' && i + 1 < b.len() && b[i + 1].is_ascii_digit());
        if starts && (i == 0 || !b[i - 1].is_ascii_alphanumeric()) {
            let j0 = i;
            i += 1;
            while i < b.len()
                && (b[i].is_ascii_digit() || b[i] == b'.' || b[i] == b'e' || b[i] == b'-')
            {
                i += 1;
            }
            out.push((j0, i));
        } else {
            i += 1;
        }
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn random_text_never_panics(text in "[\\[\\]a-z_=.,0-9\" \n{}#-]{0,300}") {
        loads_or_refuses(&text);
    }

    #[test]
    fn mutated_scene_never_panics(
        edits in prop::collection::vec((0usize..1000, 0u8..3, "[\\[\\]a-z=.,0-9\" \n-]{0,4}"), 1..6)
    ) {
        let mut text = BASE.as_bytes().to_vec();
        for (pos, kind, ins) in edits {
            let p = pos % (text.len() + 1);
            match kind {
                0 => { text.splice(p..p, ins.bytes()); }
                1 => { let e = (p + ins.len().max(1)).min(text.len()); text.drain(p..e); }
                _ => { let e = (p + ins.len()).min(text.len()); text.splice(p..e, ins.bytes()); }
            }
        }
        loads_or_refuses(&String::from_utf8_lossy(&text));
    }

    #[test]
    fn mutated_numbers_never_panic(
        picks in prop::collection::vec((0usize..100, prop_oneof![
            Just("nan".to_string()), Just("inf".to_string()), Just("-inf".to_string()),
            Just("0".to_string()), Just("-0.0".to_string()), Just("1e300".to_string()),
            Just("-1e-300".to_string()), Just("1".to_string()), Just("0.999999".to_string()),
            Just("9223372036854775807".to_string()),
            (-1.0e3f64..1.0e3).prop_map(|x| format!("{x:?}")),
            (-5i64..20).prop_map(|x| x.to_string()),
        ]), 1..4)
    ) {
        let spans = number_spans(BASE);
        let mut chosen: Vec<(usize, String)> = picks.into_iter().map(|(i, v)| (i % spans.len(), v)).collect();
        chosen.sort_by_key(|c| std::cmp::Reverse(c.0));
        chosen.dedup_by_key(|c| c.0);
        let mut text = BASE.to_string();
        for (i, v) in chosen {
            let (a, b) = spans[i];
            text.replace_range(a..b, &v);
        }
        loads_or_refuses(&text);
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    /// Mutated copies of the Cornell OBJ (and MTL) are loaded or refused, never a panic.
    /// Regression: this found tobj 4.0.5 panicking on an MTL colour with fewer than three
    /// values, and an out-of-range face-line lookup for a model without faces.
    #[test]
    fn mutated_obj_never_panics(
        edits in prop::collection::vec((0usize..4000, 0u8..3, "[fvglusemtKd0-9 ./\n-]{0,5}"), 1..8),
        mtl_edits in prop::collection::vec((0usize..2000, "[Kde0-9 .\n-]{0,4}"), 0..3),
    ) {
        let src = scenes().join("cornell-box");
        let mut obj = std::fs::read(src.join("CornellBox-Original.obj")).unwrap();
        for (pos, kind, ins) in edits {
            let p = pos % (obj.len() + 1);
            match kind {
                0 => { obj.splice(p..p, ins.bytes()); }
                1 => { let e = (p + ins.len().max(1)).min(obj.len()); obj.drain(p..e); }
                _ => { let e = (p + ins.len()).min(obj.len()); obj.splice(p..e, ins.bytes()); }
            }
        }
        let mut mtl = std::fs::read(src.join("CornellBox-Original.mtl")).unwrap();
        for (pos, ins) in mtl_edits {
            let p = pos % (mtl.len() + 1);
            mtl.splice(p..p, ins.bytes());
        }
        let dir = std::env::temp_dir().join(format!("pfs-scene-{}-objfuzz", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("CornellBox-Original.obj"), &obj).unwrap();
        std::fs::write(dir.join("CornellBox-Original.mtl"), &mtl).unwrap();
        let scene = "[camera]\neye = [0, 1, 4]\nlook_at = [0, 1, 0]\nfov_y = 40\n\n[[obj]]\nfile = \"CornellBox-Original.obj\"\n";
        let path = dir.join("s.toml");
        std::fs::write(&path, scene).unwrap();
        match load_scene(&path) {
            Ok(s) => check_invariants(&s),
            Err(e) => prop_assert_eq!(e.exit_code(), EXIT_BAD_INPUT, "{}", e),
        }
    }
}

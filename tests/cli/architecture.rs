//! The architecture points one way, at two levels.
//!
//! **Crates.** The workspace's crates are the stages data passes through, in the order of
//! [`CRATES`]: every crate's `[dependencies]` names only crates earlier in that order (no cycle,
//! no arrow upstream), and only the command line depends on the user-interface crates (argument
//! parsing, progress bars, signal handling, error context for people).
//!
//! **Modules.** Inside the crates built from several stages ([`MODULES`]), every `crate::` path
//! of non-test code names a module that comes earlier in the crate's order than the module it
//! is written in, and `lib.rs` declares the modules in that order, so a new module has to be
//! placed in the flow before it can be used. Unit tests (`#[cfg(test)]` modules, inline or in
//! their own files) are exempt: a stage's tests may run later stages to check it in context.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// The crates, upstream first (directory under `crates/`, or `.` for the binary's package at
/// the repository's root; package name).
const CRATES: &[(&str, &str)] = &[
    ("lanes", "pixelflow-lanes"),
    ("base", "pixelflow-base"),
    ("scene", "pixelflow-scene"),
    ("radiosity", "pixelflow-radiosity"),
    ("truth", "pixelflow-truth"),
    ("reconstruction", "pixelflow-reconstruction"),
    ("engine", "pixelflow-engine"),
    ("metric", "pixelflow-metric"),
    ("imageio", "pixelflow-imageio"),
    ("export", "pixelflow-export"),
    ("fixtures", "pixelflow-fixtures"),
    ("app", "pixelflow-app"),
    ("study", "pixelflow-study"),
    (".", "pixelflow-sim"),
];

/// The crates made of several stages, and their modules, upstream first.
const MODULES: &[(&str, &[&str])] = &[
    (
        "base",
        &[
            "error", "output", "progress", "image", "quadtree", "method", "rng",
        ],
    ),
    ("engine", &["raster", "composition", "shading", "frame"]),
    (
        "app",
        &[
            "context", "budget", "prepare", "memory", "frames", "rates", "commands", "report",
            "text", "viewer",
        ],
    ),
    (
        "study",
        &[
            "timing",
            "physics",
            "equal_error",
            "equal_views",
            "sweep",
            "walk_timing",
            "worker",
            "plot",
            "experiment",
        ],
    ),
];

/// Dependencies that belong to the command line only.
const USER_INTERFACE: &[&str] = &["clap", "indicatif", "ctrlc", "anyhow", "minifb"];

fn crates_dir() -> PathBuf {
    Path::new(crate::REPO).join("crates")
}

/// Every `.rs` file under `dir`, sorted.
fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

/// The package names in the `[dependencies]` table of a crate's manifest (renamed workspace
/// dependencies `scene.workspace = true` are resolved through the workspace's table).
fn dependencies(dir: &str) -> Vec<String> {
    let at = if dir == "." {
        PathBuf::from(crate::REPO)
    } else {
        crates_dir().join(dir)
    };
    let manifest = std::fs::read_to_string(at.join("Cargo.toml")).unwrap();
    let workspace = std::fs::read_to_string(Path::new(crate::REPO).join("Cargo.toml")).unwrap();
    let mut out = Vec::new();
    let mut in_deps = false;
    for line in manifest.lines() {
        let line = line.trim();
        if line.starts_with('[') {
            in_deps = line == "[dependencies]";
            continue;
        }
        if !in_deps || line.is_empty() || line.starts_with('#') {
            continue;
        }
        let key = line.split(['.', '=', ' ']).next().unwrap().to_string();
        // A workspace dependency may be renamed: `key = { package = "pixelflow-x", ... }`.
        let package = workspace
            .lines()
            .find(|l| l.starts_with(&format!("{key} =")))
            .and_then(|l| l.split("package = \"").nth(1))
            .and_then(|p| p.split('"').next())
            .map(str::to_string)
            .unwrap_or(key);
        out.push(package);
    }
    out
}

#[test]
fn every_crate_depends_only_on_crates_upstream_of_it() {
    let rank = |package: &str| CRATES.iter().position(|(_, p)| *p == package);
    let mut dirs: Vec<String> = std::fs::read_dir(crates_dir())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    dirs.sort();
    let mut listed: Vec<String> = CRATES
        .iter()
        .filter(|(d, _)| *d != ".")
        .map(|(d, _)| d.to_string())
        .collect();
    listed.sort();
    assert_eq!(dirs, listed, "crates/ holds exactly the crates of CRATES");
    let mut bad = Vec::new();
    for (k, (dir, package)) in CRATES.iter().enumerate() {
        for dep in dependencies(dir) {
            match rank(&dep) {
                Some(r) if r >= k => bad.push(format!("{package} -> {dep} (not upstream of it)")),
                _ => {}
            }
            if USER_INTERFACE.contains(&dep.as_str()) && *dir != "." {
                bad.push(format!(
                    "{package} -> {dep} (the command line's dependency)"
                ));
            }
        }
    }
    assert!(
        bad.is_empty(),
        "crate arrows against the data flow:\n{}",
        bad.join("\n")
    );
    // The scan does see the arrows.
    assert!(dependencies("engine").contains(&"pixelflow-reconstruction".to_string()));
    assert!(dependencies(".").contains(&"clap".to_string()));
}

/// `text` with comments removed and the contents of string and char literals blanked (so braces
/// and `crate::` inside them do not count). Line structure is kept.
fn strip(text: &str) -> String {
    let b = text.as_bytes();
    let mut out = String::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let c = b[i];
        if c == b'/' && b.get(i + 1) == Some(&b'/') {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
        } else if c == b'/' && b.get(i + 1) == Some(&b'*') {
            let mut depth = 0;
            while i < b.len() {
                if b[i] == b'/' && b.get(i + 1) == Some(&b'*') {
                    depth += 1;
                    i += 2;
                } else if b[i] == b'*' && b.get(i + 1) == Some(&b'/') {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    if b[i] == b'\n' {
                        out.push('\n');
                    }
                    i += 1;
                }
            }
        } else if c == b'r' && matches!(b.get(i + 1), Some(b'"') | Some(b'#')) && {
            let mut j = i + 1;
            while b.get(j) == Some(&b'#') {
                j += 1;
            }
            b.get(j) == Some(&b'"')
                && (i == 0 || !(b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_'))
        } {
            // Raw string r#"..."#.
            let mut j = i + 1;
            let mut hashes = 0;
            while b[j] == b'#' {
                hashes += 1;
                j += 1;
            }
            j += 1;
            loop {
                if j >= b.len() {
                    break;
                }
                if b[j] == b'"' && (0..hashes).all(|k| b.get(j + 1 + k) == Some(&b'#')) {
                    j += 1 + hashes;
                    break;
                }
                if b[j] == b'\n' {
                    out.push('\n');
                }
                j += 1;
            }
            out.push_str("\"\"");
            i = j;
        } else if c == b'"' {
            i += 1;
            while i < b.len() && b[i] != b'"' {
                if b[i] == b'\\' {
                    i += 1;
                }
                if i < b.len() && b[i] == b'\n' {
                    out.push('\n');
                }
                i += 1;
            }
            i += 1;
            out.push_str("\"\"");
        } else if c == b'\'' {
            // A char literal ('x', '\n', '\u{..}') or a lifetime ('a).
            let end = if b.get(i + 1) == Some(&b'\\') {
                (i + 2..b.len().min(i + 12)).find(|&j| b[j] == b'\'')
            } else if b.get(i + 2) == Some(&b'\'') {
                Some(i + 2)
            } else {
                None
            };
            match end {
                Some(j) => {
                    out.push_str("' '");
                    i = j + 1;
                }
                None => {
                    out.push('\'');
                    i += 1;
                }
            }
        } else {
            out.push(c as char);
            i += 1;
        }
    }
    out
}

/// `text` (stripped) without `#[cfg(test)]` items: an inline `mod x { ... }` is removed up to
/// its matching brace; `mod x;` is removed and `x` returned as a test-only child file.
fn remove_test_items(text: &str) -> (String, Vec<String>) {
    let mut out = String::new();
    let mut children = Vec::new();
    let mut rest = text;
    while let Some(at) = rest.find("#[cfg(test)]") {
        out.push_str(&rest[..at]);
        let after = &rest[at + "#[cfg(test)]".len()..];
        let item = after.trim_start();
        let skipped = after.len() - item.len();
        // The item: up to the first `;` or the matching `}` of its first `{`.
        let semi = item.find(';');
        let brace = item.find('{');
        let end = match (semi, brace) {
            (Some(s), Some(b)) if s < b => s + 1,
            (Some(s), None) => s + 1,
            (_, Some(b)) => {
                let mut depth = 0;
                let mut end = item.len();
                for (k, ch) in item[b..].char_indices() {
                    match ch {
                        '{' => depth += 1,
                        '}' => {
                            depth -= 1;
                            if depth == 0 {
                                end = b + k + 1;
                                break;
                            }
                        }
                        _ => {}
                    }
                }
                end
            }
            (None, None) => item.len(),
        };
        let decl = &item[..end];
        let words: Vec<&str> = decl.split_whitespace().collect();
        if let Some(k) = words.iter().position(|w| *w == "mod") {
            if let Some(name) = words.get(k + 1) {
                if let Some(name) = name.strip_suffix(';') {
                    children.push(name.to_string());
                }
            }
        }
        // Keep the line count.
        out.push_str(&"\n".repeat(after[..skipped + end].matches('\n').count()));
        rest = &after[skipped + end..];
    }
    out.push_str(rest);
    (out, children)
}

/// The crate-root modules named by `crate::` paths in `text`, with their line numbers,
/// including every member of `crate::{a, b::c}` groups.
fn crate_refs(text: &str) -> Vec<(String, usize)> {
    let mut refs = Vec::new();
    let b = text.as_bytes();
    let mut from = 0;
    while let Some(k) = text[from..].find("crate::") {
        let at = from + k;
        from = at + "crate::".len();
        // `crate` must be a whole word (not `pixelflow_crate::`, not `$crate::`).
        if at > 0 && (b[at - 1].is_ascii_alphanumeric() || b[at - 1] == b'_' || b[at - 1] == b'$') {
            continue;
        }
        let line = text[..at].matches('\n').count() + 1;
        let rest = &text[from..];
        if let Some(group) = rest.strip_prefix('{') {
            // Top-level members of the group: split on commas at brace depth 0.
            let mut depth = 0;
            let mut member = String::new();
            let mut members = Vec::new();
            for ch in group.chars() {
                match ch {
                    '{' => {
                        depth += 1;
                        member.push(ch)
                    }
                    '}' if depth == 0 => {
                        members.push(std::mem::take(&mut member));
                        break;
                    }
                    '}' => {
                        depth -= 1;
                        member.push(ch)
                    }
                    ',' if depth == 0 => members.push(std::mem::take(&mut member)),
                    _ => member.push(ch),
                }
            }
            for m in members {
                let name: String = m
                    .trim()
                    .chars()
                    .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                    .collect();
                if !name.is_empty() && name != "self" {
                    refs.push((name, line));
                }
            }
        } else {
            let name: String = rest
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                .collect();
            if !name.is_empty() {
                refs.push((name, line));
            }
        }
    }
    refs
}

/// The top-level module (of `src`) a source file belongs to (`src/raster/gbuffer.rs` ->
/// `raster`).
fn module_of(src: &Path, path: &Path) -> Option<String> {
    let rel = path.strip_prefix(src).ok()?;
    let first = rel.components().next()?.as_os_str().to_str()?;
    Some(first.trim_end_matches(".rs").to_string())
}

/// The directory a file's child modules live in (`src/a/mod.rs` -> `src/a`, `src/a/b.rs` ->
/// `src/a/b`).
fn child_dir(path: &Path) -> PathBuf {
    if path
        .file_name()
        .is_some_and(|n| n == "mod.rs" || n == "lib.rs")
    {
        path.parent().unwrap().to_path_buf()
    } else {
        path.with_extension("")
    }
}

/// Every edge `(file, line, from, to)` between the top-level modules of the crate in `src`, in
/// non-test code.
fn edges(src: &Path) -> Vec<(PathBuf, usize, String, String)> {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    let mut test_only: BTreeSet<PathBuf> = BTreeSet::new();
    let mut stripped = Vec::new();
    for f in &files {
        let (code, children) = remove_test_items(&strip(&std::fs::read_to_string(f).unwrap()));
        for c in children {
            let dir = child_dir(f);
            test_only.insert(dir.join(format!("{c}.rs")));
            test_only.insert(dir.join(&c).join("mod.rs"));
        }
        stripped.push((f.clone(), code));
    }
    let mut out = Vec::new();
    for (f, code) in stripped {
        let name = f.file_name().unwrap().to_str().unwrap();
        if name == "lib.rs" || test_only.contains(&f) {
            continue;
        }
        let Some(from) = module_of(src, &f) else {
            continue;
        };
        for (to, line) in crate_refs(&code) {
            if to != from {
                out.push((f.clone(), line, from.clone(), to));
            }
        }
    }
    out
}

#[test]
fn lib_rs_declares_the_modules_in_the_data_flow_order() {
    for (krate, order) in MODULES {
        let lib = crates_dir().join(krate).join("src/lib.rs");
        let lib = strip(&std::fs::read_to_string(lib).unwrap());
        let declared: Vec<String> = lib
            .lines()
            .filter_map(|l| l.trim().strip_prefix("pub mod "))
            .map(|m| m.trim_end_matches(';').to_string())
            .collect();
        let mut sorted = declared.clone();
        sorted.sort_by_key(|m| order.iter().position(|o| o == m));
        assert_eq!(
            declared.iter().collect::<BTreeSet<_>>(),
            order
                .iter()
                .map(|s| s.to_string())
                .collect::<BTreeSet<_>>()
                .iter()
                .collect(),
            "crates/{krate}/src/lib.rs must declare exactly the modules of MODULES"
        );
        assert_eq!(
            declared, sorted,
            "crates/{krate}/src/lib.rs: modules out of order"
        );
    }
}

#[test]
fn every_module_edge_points_down_the_data_flow() {
    let mut bad = Vec::new();
    let mut total = 0;
    for (krate, order) in MODULES {
        let src = crates_dir().join(krate).join("src");
        let rank = |m: &str| order.iter().position(|o| *o == m);
        let all = edges(&src);
        total += all.len();
        for (file, line, from, to) in &all {
            let rel = file
                .strip_prefix(Path::new(crate::REPO))
                .unwrap_or(file)
                .display();
            match (rank(from), rank(to)) {
                (Some(a), Some(b)) if b < a => {}
                (Some(_), Some(_)) => bad.push(format!(
                    "{rel}:{line}: {from} -> {to} ({to} comes after {from} in the data flow)"
                )),
                _ => bad.push(format!(
                    "{rel}:{line}: {from} -> {to} (a module missing from MODULES)"
                )),
            }
        }
    }
    assert!(total > 20, "the scan found only {total} edges");
    assert!(
        bad.is_empty(),
        "edges against the data flow:\n{}",
        bad.join("\n")
    );
}

/// The scanner itself: it sees grouped, nested and inline paths, and ignores comments, strings
/// and test modules.
#[test]
fn the_scanner_sees_every_form_of_crate_path() {
    let code = r#"
use crate::a::B;
use crate::{b, c::{D, E}, self};
fn f() { crate::d::g(); let s = "crate::x"; let c = '{'; }
// crate::y
/* crate::z */
#[cfg(test)]
mod tests { use crate::w; fn h() { let _ = "}"; } }
#[cfg(test)]
mod more;
fn k<'a>(x: &'a str) -> &'a str { crate::e::id(x) }
"#;
    let (code, children) = remove_test_items(&strip(code));
    let names: Vec<String> = crate_refs(&code).into_iter().map(|(n, _)| n).collect();
    assert_eq!(names, ["a", "b", "c", "d", "e"]);
    assert_eq!(children, ["more"]);
    // Line numbers survive stripping.
    let lines: Vec<usize> = crate_refs(&code).into_iter().map(|(_, l)| l).collect();
    assert_eq!(lines, [2, 3, 3, 4, 11]);
}

/// A crate's module tree: each module's path (`["commands", "render"]`) and its file.
fn module_files(src: &Path) -> Vec<(Vec<String>, PathBuf)> {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    files
        .into_iter()
        .filter_map(|f| {
            let rel = f.strip_prefix(src).ok()?.with_extension("");
            let mut path: Vec<String> = rel
                .components()
                .map(|c| c.as_os_str().to_string_lossy().into_owned())
                .collect();
            if matches!(
                path.last().map(String::as_str),
                Some("mod" | "lib" | "main")
            ) {
                path.pop();
            }
            Some((path, f))
        })
        .collect()
}

/// The paths a `use` tree or expression path names after its root (`a::{b, c::d}` ->
/// `[a::b, a::c::d]`), as segment lists; `self` members name the prefix itself.
fn expand_tree(text: &str) -> Vec<Vec<String>> {
    fn ident(s: &str) -> (&str, &str) {
        let n = s
            .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
            .unwrap_or(s.len());
        (&s[..n], &s[n..])
    }
    fn tree(s: &str, prefix: &[String], out: &mut Vec<Vec<String>>) -> usize {
        let mut path = prefix.to_vec();
        let mut at = 0;
        loop {
            let rest = s[at..].trim_start();
            at = s.len() - rest.len();
            if rest.starts_with('{') {
                at += 1;
                loop {
                    let inner = &s[at..];
                    let t = inner.trim_start();
                    at += inner.len() - t.len();
                    if t.starts_with('}') || t.is_empty() {
                        return at + 1;
                    }
                    at += tree(&s[at..], &path, out);
                    let t = s[at..].trim_start();
                    at = s.len() - t.len();
                    if t.starts_with(',') {
                        at += 1;
                    }
                }
            }
            let (name, after) = ident(rest);
            if name.is_empty() {
                out.push(path);
                return at;
            }
            at += name.len();
            if name != "self" {
                path.push(name.to_string());
            }
            if after.starts_with("::") {
                at += 2;
            } else {
                out.push(path);
                return at;
            }
        }
    }
    let mut out = Vec::new();
    tree(text, &[], &mut out);
    out
}

/// The module paths the non-test code of a file names through `crate::`, `super::` and
/// `self::` paths, resolved against the file's own module path `here`.
fn named_modules(code: &str, here: &[String]) -> Vec<Vec<String>> {
    let b = code.as_bytes();
    let mut out = Vec::new();
    for root in ["crate::", "super::", "self::"] {
        let mut from = 0;
        while let Some(k) = code[from..].find(root) {
            let at = from + k;
            from = at + root.len();
            let before = if at > 0 { b[at - 1] } else { b' ' };
            if before.is_ascii_alphanumeric() || before == b'_' || before == b'$' || before == b':'
            {
                continue;
            }
            // `super::` is the parent of the file's module; `self::` the module itself.
            let mut base: Vec<String> = match root {
                "crate::" => Vec::new(),
                _ => here.to_vec(),
            };
            let mut rest = &code[from..];
            if root == "super::" {
                base.pop();
                while let Some(r) = rest.strip_prefix("super::") {
                    base.pop();
                    rest = r;
                }
            }
            for p in expand_tree(rest) {
                let mut full = base.clone();
                full.extend(p);
                out.push(full);
            }
        }
    }
    out
}

/// The file-level import graph of the crate in `src`: an edge from each file to each file whose
/// module (or an item in it) its non-test code names, except a module naming its own
/// submodules (a parent declares and re-exports its children: that is the tree, not a use).
fn file_graph(src: &Path) -> Vec<(PathBuf, PathBuf)> {
    let modules = module_files(src);
    let mut test_only: BTreeSet<PathBuf> = BTreeSet::new();
    let mut codes = Vec::new();
    for (_, f) in &modules {
        let (code, children) = remove_test_items(&strip(&std::fs::read_to_string(f).unwrap()));
        for c in children {
            let dir = child_dir(f);
            test_only.insert(dir.join(format!("{c}.rs")));
            test_only.insert(dir.join(&c).join("mod.rs"));
        }
        codes.push(code);
    }
    let mut edges = BTreeSet::new();
    for ((here, f), code) in modules.iter().zip(&codes) {
        if test_only.contains(f) {
            continue;
        }
        for named in named_modules(code, here) {
            // The longest module path that prefixes the named path.
            let Some((target, file)) = modules
                .iter()
                .filter(|(m, _)| named.starts_with(m))
                .max_by_key(|(m, _)| m.len())
            else {
                continue;
            };
            let own_descendant = target.len() > here.len() && target.starts_with(here);
            if file != f && !own_descendant && !test_only.contains(file) {
                edges.insert((f.clone(), file.clone()));
            }
        }
    }
    edges.into_iter().collect()
}

/// The cycles of a directed graph, each as its strongly connected component of two or more
/// nodes (Tarjan's algorithm), sorted.
fn cycles(edges: &[(PathBuf, PathBuf)]) -> Vec<Vec<PathBuf>> {
    let nodes: Vec<PathBuf> = edges
        .iter()
        .flat_map(|(a, b)| [a.clone(), b.clone()])
        .collect::<BTreeSet<_>>()
        .into_iter()
        .collect();
    let index = |p: &PathBuf| nodes.binary_search(p).unwrap();
    let mut next: Vec<Vec<usize>> = vec![Vec::new(); nodes.len()];
    for (a, b) in edges {
        next[index(a)].push(index(b));
    }
    struct Tarjan<'a> {
        next: &'a [Vec<usize>],
        index: Vec<Option<usize>>,
        low: Vec<usize>,
        on_stack: Vec<bool>,
        stack: Vec<usize>,
        counter: usize,
        out: Vec<Vec<usize>>,
    }
    impl Tarjan<'_> {
        fn visit(&mut self, v: usize) {
            self.index[v] = Some(self.counter);
            self.low[v] = self.counter;
            self.counter += 1;
            self.stack.push(v);
            self.on_stack[v] = true;
            for k in 0..self.next[v].len() {
                let w = self.next[v][k];
                match self.index[w] {
                    None => {
                        self.visit(w);
                        self.low[v] = self.low[v].min(self.low[w]);
                    }
                    Some(i) if self.on_stack[w] => self.low[v] = self.low[v].min(i),
                    Some(_) => {}
                }
            }
            if Some(self.low[v]) == self.index[v] {
                let mut component = Vec::new();
                while let Some(w) = self.stack.pop() {
                    self.on_stack[w] = false;
                    component.push(w);
                    if w == v {
                        break;
                    }
                }
                if component.len() > 1 {
                    component.sort();
                    self.out.push(component);
                }
            }
        }
    }
    let n = nodes.len();
    let mut t = Tarjan {
        next: &next,
        index: vec![None; n],
        low: vec![0; n],
        on_stack: vec![false; n],
        stack: Vec::new(),
        counter: 0,
        out: Vec::new(),
    };
    for v in 0..n {
        if t.index[v].is_none() {
            t.visit(v);
        }
    }
    let mut out: Vec<Vec<PathBuf>> = t
        .out
        .into_iter()
        .map(|c| c.into_iter().map(|i| nodes[i].clone()).collect())
        .collect();
    out.sort();
    out
}

/// No two files of any crate (the binary's included) name each other, directly or through
/// others: every crate's files form a graph without cycles, so each can be read, tested and
/// moved from what it names alone.
#[test]
fn no_file_imports_reach_back_to_themselves() {
    let mut srcs = vec![Path::new(crate::REPO).join("src")];
    for (dir, _) in CRATES.iter().filter(|(d, _)| *d != ".") {
        srcs.push(crates_dir().join(dir).join("src"));
    }
    let mut found = Vec::new();
    let mut total = 0;
    for src in &srcs {
        let graph = file_graph(src);
        total += graph.len();
        for c in cycles(&graph) {
            let names: Vec<String> = c
                .iter()
                .map(|f| {
                    f.strip_prefix(Path::new(crate::REPO))
                        .unwrap_or(f)
                        .display()
                        .to_string()
                })
                .collect();
            found.push(names.join(" <-> "));
        }
    }
    assert!(total > 150, "the scan found only {total} file edges");
    assert!(
        found.is_empty(),
        "files that import each other:\n{}",
        found.join("\n")
    );
}

/// The file-level scan: it resolves `crate::`, `super::` and `self::` paths (grouped and
/// nested) to the longest module that holds them, and finds a cycle through three files but
/// none in a chain.
#[test]
fn the_file_scan_resolves_paths_and_finds_cycles() {
    let here = vec!["a".to_string(), "b".to_string()];
    let code = "use crate::x::{y::Z, w}; use super::c::D; use super::super::e; self::f::g();";
    let named: Vec<String> = named_modules(code, &here)
        .into_iter()
        .map(|p| p.join("::"))
        .collect();
    assert_eq!(named, ["x::y::Z", "x::w", "a::c::D", "e", "a::b::f::g"]);
    let p = |s: &str| PathBuf::from(s);
    let chain = [(p("a"), p("b")), (p("b"), p("c"))];
    assert!(cycles(&chain).is_empty());
    let ring = [
        (p("a"), p("b")),
        (p("b"), p("c")),
        (p("c"), p("a")),
        (p("c"), p("d")),
    ];
    assert_eq!(cycles(&ring), [vec![p("a"), p("b"), p("c")]]);
}

/// Longest function body allowed outside tests, in lines (signature to closing brace).
const MAX_FUNCTION_LINES: usize = 100;

/// Every function of `code` (stripped, test items removed) longer than [`MAX_FUNCTION_LINES`]:
/// its name, first line and length.
fn long_functions(code: &str) -> Vec<(String, usize, usize)> {
    let b = code.as_bytes();
    let mut out = Vec::new();
    let mut from = 0;
    while let Some(k) = code[from..].find("fn ") {
        let at = from + k;
        from = at + 3;
        if at > 0 && (b[at - 1].is_ascii_alphanumeric() || b[at - 1] == b'_') {
            continue;
        }
        let name: String = code[at + 3..]
            .chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
            .collect();
        // The body opens at the first `{` before any `;` (a declaration has none).
        let rest = &code[at..];
        let (Some(open), semi) = (rest.find('{'), rest.find(';')) else {
            continue;
        };
        if semi.is_some_and(|s| s < open) || name.is_empty() {
            continue;
        }
        let mut depth = 0;
        let mut end = None;
        for (i, ch) in rest[open..].char_indices() {
            match ch {
                '{' => depth += 1,
                '}' => {
                    depth -= 1;
                    if depth == 0 {
                        end = Some(open + i);
                        break;
                    }
                }
                _ => {}
            }
        }
        let Some(end) = end else { continue };
        let first = code[..at].matches('\n').count() + 1;
        let lines = rest[..end].matches('\n').count() + 1;
        if lines > MAX_FUNCTION_LINES {
            out.push((name, first, lines));
        }
    }
    out
}

/// No function of non-test code, in any crate or the binary, runs past [`MAX_FUNCTION_LINES`]:
/// each can be read in one screen or two.
#[test]
fn no_function_is_longer_than_a_hundred_lines() {
    let mut files = Vec::new();
    rust_files(&Path::new(crate::REPO).join("src"), &mut files);
    for (dir, _) in CRATES.iter().filter(|(d, _)| *d != ".") {
        rust_files(&crates_dir().join(dir).join("src"), &mut files);
    }
    let mut long = Vec::new();
    for f in &files {
        let name = f.file_name().unwrap().to_string_lossy();
        if name == "tests.rs" || f.components().any(|c| c.as_os_str() == "tests") {
            continue;
        }
        let (code, _) = remove_test_items(&strip(&std::fs::read_to_string(f).unwrap()));
        for (name, line, lines) in long_functions(&code) {
            let rel = f.strip_prefix(Path::new(crate::REPO)).unwrap_or(f);
            long.push(format!("{}:{line}: {name} ({lines} lines)", rel.display()));
        }
    }
    assert!(
        long.is_empty(),
        "functions over {MAX_FUNCTION_LINES} lines:\n{}",
        long.join("\n")
    );
    // The scan measures what it should.
    let body = format!(
        "fn f() {{\n{}}}\nfn g();\n",
        "x;\n".repeat(MAX_FUNCTION_LINES)
    );
    assert_eq!(
        long_functions(&body),
        [("f".to_string(), 1, MAX_FUNCTION_LINES + 2)]
    );
    let short = format!("fn f() {{\n{}}}\n", "x;\n".repeat(MAX_FUNCTION_LINES - 2));
    assert!(long_functions(&short).is_empty());
}

/// Literals in `code` that are a flag by themselves (`"--aa"`, `"-o"`): what a library would
/// pass as the name of an option, with the line of each.
fn flag_literals(code: &str) -> Vec<(usize, String)> {
    let mut found = Vec::new();
    for (n, line) in code.lines().enumerate() {
        if line.trim_start().starts_with("//") {
            continue;
        }
        for piece in line.split('"').skip(1).step_by(2) {
            let name = piece.trim_start_matches('-');
            let dashes = piece.len() - name.len();
            let word = name
                .chars()
                .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-');
            if (dashes == 2 || (dashes == 1 && name.len() == 1)) && word && !name.is_empty() {
                found.push((n + 1, piece.to_string()));
            }
        }
    }
    found
}

/// The libraries name options and settings as they know them (`aa`, `texture-size`); only the
/// binary spells them as flags (`--aa`), so a library caller reads the setting it passed and a
/// renamed flag changes one file.
#[test]
fn libraries_name_settings_not_flags() {
    let mut flags = Vec::new();
    for (dir, _) in CRATES.iter().filter(|(d, _)| *d != ".") {
        let mut files = Vec::new();
        rust_files(&crates_dir().join(dir).join("src"), &mut files);
        for f in files {
            if f.file_name().is_some_and(|n| n == "tests.rs") {
                continue;
            }
            let text = std::fs::read_to_string(&f).unwrap();
            let code = text.split("#[cfg(test)]").next().unwrap_or("");
            for (line, flag) in flag_literals(code) {
                let rel = f.strip_prefix(Path::new(crate::REPO)).unwrap_or(&f);
                flags.push(format!("{}:{line}: \"{flag}\"", rel.display()));
            }
        }
    }
    assert!(
        flags.is_empty(),
        "flags named in libraries:\n{}",
        flags.join("\n")
    );
    // The scan sees a flag passed as a name, and not a command line or a setting.
    let code = "f(\"--aa\", 1);\ng(\"-o\");\nh(\"aa\", \"run --aa 4\", \"-\");\n// \"--x\"\n";
    assert_eq!(
        flag_literals(code),
        [(1, "--aa".to_string()), (2, "-o".to_string())]
    );
}

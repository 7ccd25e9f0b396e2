//! The source tree's shape: no file-level import cycle in `src/`, and no `src/` file over 800 lines.
//!
//! Each file's imports are read from its text: every `crate::`, `super::` and `self::` path, in `use`
//! trees and inline, tests included. A path names the file of the deepest module it reaches; an item a
//! module re-exports (`pub use child::Item`) names the file that defines it, so using a folder's
//! re-exports is no edge to the folder's `mod.rs`. `mod` declarations are not imports, and a folder's
//! `mod.rs` and the files inside it are one module tree (children see their parent's private items):
//! edges between them are not counted. The crate root (`lib.rs`, `main.rs`) only declares and
//! re-exports, and is left out.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Longest file allowed in `src/`, lines.
const MAX_LINES: usize = 800;

/// One source file as a module: its path in the crate (`["plan", "lod"]`) and its text.
struct Module {
    path: Vec<String>,
    text: String,
}

fn modules() -> BTreeMap<PathBuf, Module> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut out = BTreeMap::new();
    let mut stack = vec![src.clone()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).expect("src is readable").flatten() {
            let p = entry.path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|e| e == "rs") {
                let rel = p.strip_prefix(&src).expect("under src");
                let mut path: Vec<String> = rel
                    .iter()
                    .map(|s| s.to_string_lossy().trim_end_matches(".rs").to_string())
                    .collect();
                if path
                    .last()
                    .is_some_and(|l| l == "mod" || l == "lib" || l == "main")
                {
                    path.pop();
                }
                let text = std::fs::read_to_string(&p).expect("a source file is readable");
                out.insert(rel.to_path_buf(), Module { path, text });
            }
        }
    }
    out
}

/// The code of `text` without comments and string literals (their words are no imports).
fn code_of(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let b = text.as_bytes();
    let mut i = 0;
    while i < b.len() {
        if b[i..].starts_with(b"//") {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
        } else if b[i..].starts_with(b"/*") {
            i += 2;
            while i < b.len() && !b[i..].starts_with(b"*/") {
                i += 1;
            }
            i += 2;
        } else if b[i] == b'"' && !(i > 0 && b[i - 1] == b'\'' && b.get(i + 1) == Some(&b'\'')) {
            // A string literal, raw or not (r"..", r#".."#: its hashes are skipped by the scan).
            i += 1;
            while i < b.len() && b[i] != b'"' {
                if b[i] == b'\\' {
                    i += 1;
                }
                i += 1;
            }
            i += 1;
            out.push(' ');
        } else {
            out.push(char::from(b[i]));
            i += 1;
        }
    }
    out
}

/// Every path `code` names from `crate`, `super` or `self`, as segments (use trees expanded).
fn paths(code: &str) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    let b: Vec<char> = code.chars().collect();
    let mut i = 0;
    while i < b.len() {
        let starts = ["crate::", "super::", "self::"]
            .iter()
            .find(|p| b[i..].iter().take(p.len()).copied().eq(p.chars()));
        let boundary =
            i == 0 || !(b[i - 1].is_alphanumeric() || b[i - 1] == '_' || b[i - 1] == ':');
        match starts {
            Some(p) if boundary => {
                let head = p.trim_end_matches("::").to_string();
                i = tree(&b, i + p.len(), vec![head], &mut out);
            }
            _ => i += 1,
        }
    }
    out
}

/// Reads a use tree at `i` (after `prefix::`), pushing each full path; returns where it ends.
fn tree(b: &[char], mut i: usize, prefix: Vec<String>, out: &mut Vec<Vec<String>>) -> usize {
    let mut path = prefix;
    loop {
        while i < b.len() && b[i].is_whitespace() {
            i += 1;
        }
        if i < b.len() && b[i] == '{' {
            i += 1;
            loop {
                while i < b.len() && (b[i].is_whitespace() || b[i] == ',') {
                    i += 1;
                }
                if i >= b.len() || b[i] == '}' {
                    return i + 1;
                }
                i = tree(b, i, path.clone(), out);
            }
        }
        let start = i;
        while i < b.len() && (b[i].is_alphanumeric() || b[i] == '_') {
            i += 1;
        }
        let seg: String = b[start..i].iter().collect();
        if !seg.is_empty() && seg != "self" {
            path.push(seg);
        }
        if b[i..].iter().take(2).copied().eq("::".chars()) {
            i += 2;
            continue;
        }
        out.push(path);
        return i;
    }
}

/// What the crate's modules are and what each re-exports: module path -> file, and (module path, item)
/// -> the module path the item comes from.
struct Index {
    files: BTreeMap<Vec<String>, PathBuf>,
    reexports: BTreeMap<(Vec<String>, String), Vec<String>>,
}

impl Index {
    fn new(mods: &BTreeMap<PathBuf, Module>) -> Self {
        let files = mods
            .iter()
            .map(|(f, m)| (m.path.clone(), f.clone()))
            .collect();
        let mut reexports = BTreeMap::new();
        for m in mods.values() {
            let code = code_of(&m.text);
            for stmt in code.split(';') {
                let s = stmt.trim();
                let Some(rest) = s
                    .strip_prefix("pub use ")
                    .or_else(|| s.strip_prefix("pub(crate) use "))
                else {
                    continue;
                };
                // `pub use child::Item` or `pub use crate::a::Item`: the tree read as a relative path.
                let rest = rest.trim_start_matches("self::");
                let chars: Vec<char> = rest.chars().collect();
                let mut items = Vec::new();
                tree(&chars, 0, Vec::new(), &mut items);
                for full in items {
                    let Some((item, from)) = full.split_last() else {
                        continue;
                    };
                    let from = match from.first().map(String::as_str) {
                        Some("crate") => from[1..].to_vec(),
                        _ => m.path.iter().chain(from).cloned().collect(),
                    };
                    reexports.insert((m.path.clone(), item.clone()), from);
                }
            }
        }
        Self { files, reexports }
    }

    /// The file a path from module `at` names, when it is one of the crate's own.
    fn resolve(&self, at: &[String], path: &[String]) -> Option<PathBuf> {
        let mut module: Vec<String> = match path.first().map(String::as_str) {
            Some("crate") => Vec::new(),
            Some("super") => at[..at.len().saturating_sub(1)].to_vec(),
            Some("self") => at.to_vec(),
            _ => return None,
        };
        let mut rest = &path[1..];
        while let Some(("super", tail)) = rest.split_first().map(|(h, t)| (h.as_str(), t)) {
            module.pop();
            rest = tail;
        }
        // Down the modules, then through one re-export per step.
        for _ in 0..8 {
            while let Some((seg, tail)) = rest.split_first() {
                let mut deeper = module.clone();
                deeper.push(seg.clone());
                if !self.files.contains_key(&deeper) {
                    break;
                }
                module = deeper;
                rest = tail;
            }
            match rest.first() {
                Some(item) => match self.reexports.get(&(module.clone(), item.clone())) {
                    Some(from) if *from != module => {
                        module = from.clone();
                        continue;
                    }
                    _ => break,
                },
                None => break,
            }
        }
        self.files.get(&module).cloned()
    }
}

/// Whether one of `a`, `b` is a folder's `mod.rs` and the other lies inside that folder.
fn same_tree(a: &Path, b: &Path) -> bool {
    let inside = |m: &Path, f: &Path| {
        m.file_name().is_some_and(|n| n == "mod.rs")
            && m.parent().is_some_and(|dir| f.starts_with(dir))
    };
    inside(a, b) || inside(b, a)
}

/// The file-level import graph of `src/` (the crate roots left out).
fn graph() -> BTreeMap<PathBuf, BTreeSet<PathBuf>> {
    let mods = modules();
    let index = Index::new(&mods);
    let roots = [PathBuf::from("lib.rs"), PathBuf::from("main.rs")];
    let mut g = BTreeMap::new();
    for (f, m) in &mods {
        if roots.contains(f) {
            continue;
        }
        let code = code_of(&m.text);
        let mut to = BTreeSet::new();
        for p in paths(&code) {
            if let Some(t) = index.resolve(&m.path, &p) {
                if t != *f && !roots.contains(&t) && !same_tree(f, &t) {
                    to.insert(t);
                }
            }
        }
        g.insert(f.clone(), to);
    }
    g
}

/// The strongly connected components of more than one file (Tarjan).
fn cycles(g: &BTreeMap<PathBuf, BTreeSet<PathBuf>>) -> Vec<Vec<PathBuf>> {
    struct State<'a> {
        g: &'a BTreeMap<PathBuf, BTreeSet<PathBuf>>,
        index: BTreeMap<&'a PathBuf, usize>,
        low: BTreeMap<&'a PathBuf, usize>,
        stack: Vec<&'a PathBuf>,
        on: BTreeSet<&'a PathBuf>,
        out: Vec<Vec<PathBuf>>,
    }
    fn visit<'a>(s: &mut State<'a>, v: &'a PathBuf) {
        let n = s.index.len();
        s.index.insert(v, n);
        s.low.insert(v, n);
        s.stack.push(v);
        s.on.insert(v);
        let g = s.g;
        for w in g.get(v).into_iter().flatten() {
            if !s.index.contains_key(w) {
                visit(s, w);
                let lw = s.low[w];
                let lv = s.low.get_mut(v).expect("visited");
                *lv = (*lv).min(lw);
            } else if s.on.contains(w) {
                let iw = s.index[w];
                let lv = s.low.get_mut(v).expect("visited");
                *lv = (*lv).min(iw);
            }
        }
        if s.low[v] == s.index[v] {
            let mut comp = Vec::new();
            while let Some(w) = s.stack.pop() {
                s.on.remove(w);
                comp.push(w.clone());
                if w == v {
                    break;
                }
            }
            if comp.len() > 1 {
                comp.sort();
                s.out.push(comp);
            }
        }
    }
    let mut s = State {
        g,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        out: Vec::new(),
    };
    for v in g.keys() {
        if !s.index.contains_key(v) {
            visit(&mut s, v);
        }
    }
    s.out
}

#[test]
fn no_file_level_import_cycles() {
    let g = graph();
    assert!(g.len() > 50, "read only {} files", g.len());
    let found = cycles(&g);
    assert!(
        found.is_empty(),
        "file-level import cycles in src/: {found:#?}"
    );
}

#[test]
fn no_source_file_over_800_lines() {
    let long: Vec<String> = modules()
        .iter()
        .filter(|(_, m)| m.text.lines().count() > MAX_LINES)
        .map(|(f, m)| format!("src/{} ({} lines)", f.display(), m.text.lines().count()))
        .collect();
    assert!(long.is_empty(), "over {MAX_LINES} lines: {long:?}");
}

/// The scan itself: use trees, inline paths, `super`, re-exports and a cycle are all seen.
#[test]
fn the_scan_sees_imports_and_cycles() {
    let code = code_of(
        "use crate::plan::{lod::{Lod, LodMode}, clipmap::Clipmap};\n\
         // crate::not::this\n let x = super::sibling::f(\"crate::nor::this\");",
    );
    let p = paths(&code);
    let want: Vec<Vec<String>> = [
        &["crate", "plan", "lod", "Lod"][..],
        &["crate", "plan", "lod", "LodMode"],
        &["crate", "plan", "clipmap", "Clipmap"],
        &["super", "sibling", "f"],
    ]
    .iter()
    .map(|v| v.iter().map(|s| (*s).to_string()).collect())
    .collect();
    assert_eq!(p, want);

    let g = graph();
    // The SAT LOD selector imports the bake's tables; a re-exported item names its defining file.
    let lod = &g[Path::new("plan/lod/mod.rs")];
    assert!(lod.contains(Path::new("bake/lod_tables.rs")), "{lod:?}");
    let a = PathBuf::from("a.rs");
    let b = PathBuf::from("b.rs");
    let two = BTreeMap::from([
        (a.clone(), BTreeSet::from([b.clone()])),
        (b.clone(), BTreeSet::from([a.clone()])),
    ]);
    assert_eq!(cycles(&two), vec![vec![a, b]]);
}

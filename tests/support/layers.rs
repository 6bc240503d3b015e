//! A check of a crate's module layering, from its source text alone: which top-level modules
//! each file refers to through `crate::…` paths, whether those references form a cycle, and
//! whether any points up a declared order of layers.
//!
//! Generic over the source directory and the layer table, so any crate of the workspace can be
//! checked (`check_layers(Path::new("primitives/src"), &[…])`).
//!
//! What counts as a reference: a `crate::NAME` path in code (in a `use`, a path expression, a
//! type, a `pub(in crate::NAME)`), `NAME` being one of the directory's top-level modules (a file
//! `NAME.rs` or a folder `NAME/`), and each top-level name of a group `crate::{a::x, b}`.
//! Comments (line, block, doc) and string and character literals are skipped, so a doc link to
//! a higher layer is no import. `super::` paths are not followed: inside a top-level module they
//! stay within it, which the layering does not constrain.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Where one reference was found.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct Site {
    /// The file, relative to the checked directory.
    pub file: PathBuf,
    /// 1-based line.
    pub line: usize,
}

/// For each top-level module, the top-level modules it refers to (never itself), each with the
/// first place it does.
pub type Imports = BTreeMap<String, BTreeMap<String, Site>>;

/// Every `.rs` file under `dir`, sorted, with its path relative to `dir`.
pub fn rust_files(dir: &Path) -> Vec<(PathBuf, PathBuf)> {
    fn walk(root: &Path, dir: &Path, out: &mut Vec<(PathBuf, PathBuf)>) {
        let mut entries: Vec<_> = std::fs::read_dir(dir)
            .unwrap_or_else(|e| panic!("reading {}: {e}", dir.display()))
            .map(|e| e.expect("a directory entry").path())
            .collect();
        entries.sort();
        for path in entries {
            if path.is_dir() {
                walk(root, &path, out);
            } else if path.extension().is_some_and(|x| x == "rs") {
                let rel = path.strip_prefix(root).expect("under the root").to_path_buf();
                out.push((path, rel));
            }
        }
    }
    let mut out = Vec::new();
    walk(dir, dir, &mut out);
    out
}

/// The top-level modules of the crate whose source is `dir`: `NAME.rs` files and `NAME/`
/// folders, less the crate roots `lib.rs` and `main.rs`.
pub fn top_level_modules(dir: &Path) -> BTreeSet<String> {
    let mut names = BTreeSet::new();
    for entry in std::fs::read_dir(dir).unwrap_or_else(|e| panic!("reading {}: {e}", dir.display())) {
        let path = entry.expect("a directory entry").path();
        let name = path.file_stem().expect("a name").to_string_lossy().into_owned();
        if path.is_dir() || (path.extension().is_some_and(|x| x == "rs") && name != "lib" && name != "main") {
            names.insert(name);
        }
    }
    names
}

/// The top-level module a file (relative to the source directory) belongs to; `None` for the
/// crate roots.
pub fn owner(rel: &Path) -> Option<String> {
    let first = rel.components().next()?.as_os_str().to_string_lossy().into_owned();
    match first.strip_suffix(".rs") {
        Some("lib" | "main") => None,
        Some(stem) => Some(stem.to_string()),
        None => Some(first),
    }
}

/// `source` with comments and string and character literals replaced by spaces (line breaks
/// kept, so line numbers still hold).
pub fn code_only(source: &str) -> String {
    let chars: Vec<char> = source.chars().collect();
    let mut out = String::with_capacity(source.len());
    let blank = |c: char| if c == '\n' { '\n' } else { ' ' };
    let is_ident = |c: char| c.is_alphanumeric() || c == '_';
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        let next = chars.get(i + 1).copied();
        if c == '/' && next == Some('/') {
            while i < chars.len() && chars[i] != '\n' {
                out.push(' ');
                i += 1;
            }
        } else if c == '/' && next == Some('*') {
            // block comments nest in Rust
            let mut depth = 0;
            while i < chars.len() {
                if chars[i] == '/' && chars.get(i + 1) == Some(&'*') {
                    depth += 1;
                    out.push_str("  ");
                    i += 2;
                } else if chars[i] == '*' && chars.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    out.push_str("  ");
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    out.push(blank(chars[i]));
                    i += 1;
                }
            }
        } else if c == 'r' && (next == Some('"') || next == Some('#')) && (i == 0 || !is_ident(chars[i - 1])) {
            // a raw string `r"…"`, `r#"…"#` (or `br…`: the `b` was copied as code)
            let mut j = i + 1;
            while chars.get(j) == Some(&'#') {
                j += 1;
            }
            if chars.get(j) != Some(&'"') {
                out.push(c);
                i += 1;
                continue;
            }
            let hashes = j - i - 1;
            let mut k = j + 1;
            while k < chars.len() && !(chars[k] == '"' && (1..=hashes).all(|h| chars.get(k + h) == Some(&'#'))) {
                k += 1;
            }
            let end = (k + 1 + hashes).min(chars.len());
            out.extend(chars[i..end].iter().map(|&c| blank(c)));
            i = end;
        } else if c == '"' {
            out.push(' ');
            i += 1;
            while i < chars.len() && chars[i] != '"' {
                if chars[i] == '\\' {
                    out.push(' ');
                    i += 1;
                }
                if i < chars.len() {
                    out.push(blank(chars[i]));
                    i += 1;
                }
            }
            out.push(' ');
            i += 1;
        } else if c == '\'' {
            // a character literal (`'x'`, `'\n'`, `'\u{1F600}'`), or else a lifetime or label
            let literal_end = if next == Some('\\') {
                (i + 2..chars.len()).find(|&k| chars[k] == '\'')
            } else if chars.get(i + 2) == Some(&'\'') {
                Some(i + 2)
            } else {
                None
            };
            match literal_end {
                Some(end) => {
                    out.extend(std::iter::repeat_n(' ', end + 1 - i));
                    i = end + 1;
                }
                None => {
                    out.push(c);
                    i += 1;
                }
            }
        } else {
            out.push(c);
            i += 1;
        }
    }
    out
}

/// The `crate::NAME` references of `code` (already [`code_only`]): each top-level `NAME` with
/// its 1-based line, a group `crate::{a, b::c}` giving `a` and `b`.
pub fn crate_references(code: &str) -> Vec<(String, usize)> {
    let mut found = Vec::new();
    let ident = |s: &str| -> String { s.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect() };
    for (at, _) in code.match_indices("crate::") {
        // not the tail of a longer name (`$crate::`, `my_crate::`)
        if code[..at]
            .chars()
            .next_back()
            .is_some_and(|c| c.is_alphanumeric() || c == '_' || c == '$')
        {
            continue;
        }
        let line = code[..at].matches('\n').count() + 1;
        let rest = code[at + "crate::".len()..].trim_start();
        if let Some(group) = rest.strip_prefix('{') {
            // the names at depth 1 of the group: after `{` and after each `,` at that depth
            let mut depth = 1;
            let mut expect_name = true;
            for (k, c) in group.char_indices() {
                match c {
                    '{' => depth += 1,
                    '}' => {
                        depth -= 1;
                        if depth == 0 {
                            break;
                        }
                    }
                    ',' if depth == 1 => expect_name = true,
                    c if expect_name && depth == 1 && !c.is_whitespace() => {
                        expect_name = false;
                        let name = ident(&group[k..]);
                        if !name.is_empty() {
                            let line = line + group[..k].matches('\n').count();
                            found.push((name, line));
                        }
                    }
                    _ => {}
                }
            }
        } else {
            let name = ident(rest);
            if !name.is_empty() {
                found.push((name, line));
            }
        }
    }
    found
}

/// The references between the top-level modules of the crate whose source is `dir`.
pub fn imports(dir: &Path) -> Imports {
    let modules = top_level_modules(dir);
    let mut imports: Imports = modules.iter().map(|m| (m.clone(), BTreeMap::new())).collect();
    for (path, rel) in rust_files(dir) {
        let Some(from) = owner(&rel) else { continue };
        let source = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("reading {}: {e}", path.display()));
        for (to, line) in crate_references(&code_only(&source)) {
            if to != from && modules.contains(&to) {
                let site = Site {
                    file: rel.clone(),
                    line,
                };
                imports.entry(from.clone()).or_default().entry(to).or_insert(site);
            }
        }
    }
    imports
}

/// The cycles of `imports`: each strongly connected set of two or more modules, as one path
/// around it (`a -> b -> a`), sorted.
pub fn cycles(imports: &Imports) -> Vec<Vec<String>> {
    // Tarjan's strongly connected components
    struct State<'a> {
        imports: &'a Imports,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        on_stack: BTreeSet<&'a str>,
        components: Vec<Vec<&'a str>>,
    }
    fn visit<'a>(s: &mut State<'a>, v: &'a str) {
        let n = s.index.len();
        s.index.insert(v, n);
        s.low.insert(v, n);
        s.stack.push(v);
        s.on_stack.insert(v);
        let imports = s.imports;
        for w in imports.get(v).into_iter().flat_map(|m| m.keys()) {
            let w = w.as_str();
            if !s.index.contains_key(w) {
                visit(s, w);
                let low = s.low[v].min(s.low[w]);
                s.low.insert(v, low);
            } else if s.on_stack.contains(w) {
                let low = s.low[v].min(s.index[w]);
                s.low.insert(v, low);
            }
        }
        if s.low[v] == s.index[v] {
            let mut component = Vec::new();
            loop {
                let w = s.stack.pop().expect("v is on the stack");
                s.on_stack.remove(w);
                component.push(w);
                if w == v {
                    break;
                }
            }
            s.components.push(component);
        }
    }
    let mut s = State {
        imports,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on_stack: BTreeSet::new(),
        components: Vec::new(),
    };
    for v in imports.keys() {
        if !s.index.contains_key(v.as_str()) {
            visit(&mut s, v);
        }
    }
    let mut cycles: Vec<Vec<String>> = s
        .components
        .into_iter()
        .filter(|c| c.len() > 1)
        .map(|component| {
            // one path around the component: breadth-first from its smallest module back to it
            let members: BTreeSet<&str> = component.into_iter().collect();
            let start = *members.first().expect("not empty");
            let mut came_from: BTreeMap<&str, &str> = BTreeMap::new();
            let mut queue = std::collections::VecDeque::from([start]);
            let mut last = start;
            'search: while let Some(v) = queue.pop_front() {
                for w in imports[v].keys().map(String::as_str).filter(|w| members.contains(w)) {
                    if w == start {
                        last = v;
                        break 'search;
                    }
                    if !came_from.contains_key(w) {
                        came_from.insert(w, v);
                        queue.push_back(w);
                    }
                }
            }
            let mut path = vec![start.to_string()];
            let mut v = last;
            while v != start {
                path.push(v.to_string());
                v = came_from[v];
            }
            path.push(start.to_string());
            let end = path.len() - 1;
            path[1..end].reverse();
            path
        })
        .collect();
    cycles.sort();
    cycles
}

/// Everything wrong with the layering of the crate whose source is `dir` against `layers`
/// (bottom first; a module may import its own layer's modules and the layers below): a
/// top-level module missing from the table or listed but absent, each cycle, and each import of
/// a module in a higher layer. Empty when the layering holds.
pub fn check_layers(dir: &Path, layers: &[&[&str]]) -> Vec<String> {
    let mut problems = Vec::new();
    let rank: BTreeMap<&str, usize> = layers
        .iter()
        .enumerate()
        .flat_map(|(r, layer)| layer.iter().map(move |&m| (m, r)))
        .collect();
    let modules = top_level_modules(dir);
    for m in &modules {
        if !rank.contains_key(m.as_str()) {
            problems.push(format!("module `{m}` is in no layer"));
        }
    }
    for m in rank.keys() {
        if !modules.contains(*m) {
            problems.push(format!(
                "layer table lists `{m}`, which {} does not have",
                dir.display()
            ));
        }
    }
    let imports = imports(dir);
    for cycle in cycles(&imports) {
        problems.push(format!("import cycle: {}", cycle.join(" -> ")));
    }
    for (from, tos) in &imports {
        for (to, site) in tos {
            if let (Some(&a), Some(&b)) = (rank.get(from.as_str()), rank.get(to.as_str())) {
                if b > a {
                    problems.push(format!(
                        "`{from}` (layer {}) imports `{to}` (layer {}, above) at {}:{}",
                        a + 1,
                        b + 1,
                        site.file.display(),
                        site.line
                    ));
                }
            }
        }
    }
    problems
}

/// The `.rs` files under `dir` longer than `max_lines` lines, with their lengths.
pub fn files_longer_than(dir: &Path, max_lines: usize) -> Vec<(PathBuf, usize)> {
    rust_files(dir)
        .into_iter()
        .filter_map(|(path, rel)| {
            let lines = std::fs::read_to_string(&path).expect("readable").lines().count();
            (lines > max_lines).then_some((rel, lines))
        })
        .collect()
}

//! The crate's module layering (see `src/lib.rs`, "Layers"): no import cycle between its
//! top-level modules, no import pointing up the layer order, no source file over 800 lines.
//! The checker itself (`support::layers`) is tested here on small made-up crates.

mod support;

use std::path::Path;
use support::layers::{check_layers, code_only, crate_references, cycles, files_longer_than, imports};

/// The layers of `src/`, bottom first, as `src/lib.rs` states them.
const SRC_LAYERS: &[&[&str]] = &[
    &["motion", "sampling", "camera", "aov", "resources"],
    &["scene"],
    &["trace", "diagnostics"],
    &["render", "query"],
    &["output"],
    &["cli"],
];

/// The most lines a source file of `src/` may have.
const MAX_LINES: usize = 800;

fn src() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

#[test]
fn src_modules_import_only_downward_and_without_cycles() {
    let problems = check_layers(&src(), SRC_LAYERS);
    assert!(problems.is_empty(), "layering of src/:\n{}", problems.join("\n"));
    // the check saw the real imports: the pipeline's main edges are there
    let found = imports(&src());
    for (from, to) in [
        ("trace", "scene"),
        ("render", "trace"),
        ("query", "scene"),
        ("output", "render"),
        ("cli", "output"),
    ] {
        assert!(found[from].contains_key(to), "{from} -> {to} not found: {found:?}");
    }
    // render and query sit side by side and neither uses the other
    assert!(!found["render"].contains_key("query") && !found["query"].contains_key("render"));
}

#[test]
fn src_files_are_at_most_800_lines() {
    let long = files_longer_than(&src(), MAX_LINES);
    assert!(long.is_empty(), "files over {MAX_LINES} lines: {long:?}");
}

/// A crate source directory of `files` (path, text) in a fresh temporary directory.
fn crate_of(files: &[(&str, &str)]) -> tempfile::TempDir {
    let dir = tempfile::tempdir().expect("a temporary directory");
    for (path, text) in files {
        let path = dir.path().join(path);
        std::fs::create_dir_all(path.parent().expect("a parent")).expect("folders made");
        std::fs::write(path, text).expect("written");
    }
    dir
}

#[test]
fn comments_strings_and_characters_are_not_code() {
    let code = code_only(
        "use crate::a; // crate::b\n/* crate::c /* nested crate::d */ crate::e */ let s = \"crate::f \\\" crate::g\";\n\
         let r = r#\"crate::h \"# ; let q = '\"'; let l: &'static str = crate::i::X; /// crate::j\n",
    );
    let names: Vec<_> = crate_references(&code).into_iter().map(|(n, _)| n).collect();
    assert_eq!(names, ["a", "i"]);
    assert_eq!(code.lines().count(), 3, "line breaks are kept");
}

#[test]
fn grouped_imports_give_each_top_level_name_and_its_line() {
    let code = code_only("fn f() {}\nuse crate::{\n    a::{x, y::Z},\n    b,\n    c::w as v,\n};\nuse my_crate::d;\n");
    assert_eq!(
        crate_references(&code),
        [("a".to_string(), 3), ("b".to_string(), 4), ("c".to_string(), 5)]
    );
}

#[test]
fn a_layered_crate_passes_and_its_imports_are_found() {
    let dir = crate_of(&[
        ("lib.rs", "pub mod base; pub mod mid; pub mod top;"),
        ("base.rs", "pub struct B;"),
        (
            "mid/mod.rs",
            "mod inner;\nuse crate::base::B;\n/// [`crate::top`] is only named in a doc\npub fn m(_: B) {}",
        ),
        (
            "mid/inner.rs",
            "use crate::mid::m; use crate::base::B; pub fn i() { m(B) }",
        ),
        ("top.rs", "use crate::{base::B, mid};\npub fn t() { mid::m(B) }"),
    ]);
    assert_eq!(
        check_layers(dir.path(), &[&["base"], &["mid"], &["top"]]),
        Vec::<String>::new()
    );
    let found = imports(dir.path());
    assert_eq!(found["mid"].keys().collect::<Vec<_>>(), ["base"]);
    assert_eq!(found["top"].keys().collect::<Vec<_>>(), ["base", "mid"]);
    assert!(found["base"].is_empty());
}

#[test]
fn an_upward_import_and_a_cycle_are_reported_where_they_are() {
    let dir = crate_of(&[
        ("lib.rs", "pub mod a; pub mod b; pub mod c; pub mod d;"),
        ("a.rs", "pub fn a() {}"),
        ("b.rs", "pub fn b() {}\n\npub fn up() { crate::d::d() }"),
        ("c/mod.rs", "mod x;\npub fn c() {}"),
        ("c/x.rs", "use crate::d::d;"),
        ("d.rs", "use crate::c::c;\npub fn d() { c() }"),
    ]);
    let problems = check_layers(dir.path(), &[&["a"], &["b"], &["c", "d"]]);
    assert_eq!(
        problems,
        [
            "import cycle: c -> d -> c",
            "`b` (layer 2) imports `d` (layer 3, above) at b.rs:3"
        ],
        "{problems:?}"
    );
    assert_eq!(cycles(&imports(dir.path())), [["c", "d", "c"]]);
}

#[test]
fn a_longer_cycle_is_one_path_around_it() {
    let dir = crate_of(&[
        ("a.rs", "use crate::b::X;"),
        ("b.rs", "use crate::c::X;"),
        ("c.rs", "use crate::a::X;"),
        ("e.rs", "use crate::a::X;"),
    ]);
    assert_eq!(cycles(&imports(dir.path())), [["a", "b", "c", "a"]]);
}

#[test]
fn modules_outside_the_table_and_long_files_are_named() {
    let dir = crate_of(&[("a.rs", "fn a() {}\n"), ("b.rs", &"// line\n".repeat(801))]);
    assert_eq!(
        check_layers(dir.path(), &[&["a", "gone"]]),
        [
            "module `b` is in no layer",
            &format!("layer table lists `gone`, which {} does not have", dir.path().display())
        ]
    );
    assert_eq!(
        files_longer_than(dir.path(), 800),
        [(Path::new("b.rs").to_path_buf(), 801)]
    );
    assert!(files_longer_than(dir.path(), 801).is_empty());
}

fn primitives_src() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("primitives").join("src")
}

/// The kernel crate has no import cycle between its top-level modules.
#[test]
fn primitives_modules_have_no_import_cycles() {
    let found = imports(&primitives_src());
    // the check saw the real imports: the finders depend on what a surface is
    for (from, to) in [("traits", "implicit"), ("root", "isolation"), ("isolation", "finder")] {
        assert!(found[from].contains_key(to), "{from} -> {to} not found: {found:?}");
    }
    let found_cycles = cycles(&found);
    assert!(
        found_cycles.is_empty(),
        "import cycles in primitives/src: {found_cycles:?}"
    );
}

#[test]
fn primitives_files_are_at_most_800_lines() {
    let long = files_longer_than(&primitives_src(), MAX_LINES);
    assert!(long.is_empty(), "files over {MAX_LINES} lines: {long:?}");
}

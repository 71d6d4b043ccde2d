//! The module order of ARCHITECTURE.md holds (issue #32): within each crate, a module refers
//! (`crate::module`, anywhere outside comments) only to modules before it in the order the
//! file writes down, except for the arrows back up it lists as known — and each of those
//! must still exist, so the list shrinks as they are removed. A new module must be placed in
//! the order before it can be used. And the crates depend on one another only as the crates
//! table of ARCHITECTURE.md allows (issue #56), as `cargo metadata` reads the manifests,
//! and no folder's files refer to one another in a circle.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The lines of the fenced block of ARCHITECTURE.md that follows the line `marker`.
fn block(text: &str, marker: &str) -> Vec<String> {
    text.lines()
        .skip_while(|l| l.trim() != marker)
        .skip(1)
        .skip_while(|l| !l.trim_start().starts_with("```"))
        .skip(1)
        .take_while(|l| !l.trim_start().starts_with("```"))
        .map(str::to_owned)
        .collect()
}

/// The module order per crate source folder: `folder: a b c`.
fn orders(text: &str) -> BTreeMap<String, Vec<String>> {
    block(text, "<!-- module order -->")
        .iter()
        .filter_map(|l| l.split_once(':'))
        .map(|(folder, modules)| (folder.trim().to_owned(), modules.split_whitespace().map(str::to_owned).collect()))
        .collect()
}

/// The known arrows back up: `folder: from -> to`.
fn exceptions(text: &str) -> BTreeSet<(String, String, String)> {
    block(text, "<!-- known arrows back up -->")
        .iter()
        .filter_map(|l| {
            let (folder, arrow) = l.split_once(':')?;
            let (from, to) = arrow.split_once("->")?;
            Some((folder.trim().to_owned(), from.trim().to_owned(), to.trim().to_owned()))
        })
        .collect()
}

/// The source without `//` comments (doc comments included).
fn without_comments(source: &str) -> String {
    source.lines().map(|l| l.split_once("//").map_or(l, |(code, _)| code)).collect::<Vec<_>>().join("\n")
}

/// The top-level names a source refers to as `crate::name` or inside `crate::{a, b::c}`.
fn crate_references(source: &str) -> BTreeSet<String> {
    references_after(source, "crate::")
}

/// The names a source refers to right after `prefix` (`crate::`, `super::`, a folder's
/// `crate::a::b::`), alone or inside braces.
fn references_after(source: &str, prefix: &str) -> BTreeSet<String> {
    let mut names = BTreeSet::new();
    let ident = |s: &str| s.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect::<String>();
    let mut rest = source;
    while let Some(at) = rest.find(prefix) {
        rest = &rest[at + prefix.len()..];
        // `super::super::x` names the grandparent's `x`, not a sibling.
        if prefix == "super::" && rest.starts_with("super::") {
            rest = rest.trim_start_matches("super::");
            continue;
        }
        if let Some(inner) = rest.strip_prefix('{') {
            // The names right after the brace or a comma at depth one.
            let (mut depth, mut expecting) = (1, true);
            for (i, c) in inner.char_indices() {
                match c {
                    '{' => depth += 1,
                    '}' if depth == 1 => {
                        rest = &inner[i..];
                        break;
                    }
                    '}' => depth -= 1,
                    ',' if depth == 1 => expecting = true,
                    c if c.is_whitespace() => {}
                    _ if expecting && depth == 1 => {
                        names.insert(ident(&inner[i..]));
                        expecting = false;
                    }
                    _ => {}
                }
            }
        } else {
            names.insert(ident(rest));
        }
    }
    names
}

/// Every module of a crate's source folder (files and folders but `lib.rs`/`main.rs`) and the
/// modules each refers to.
fn references(folder: &Path) -> BTreeMap<String, BTreeSet<String>> {
    let module_of = |p: &Path| {
        let first = p.strip_prefix(folder).expect("inside").components().next().expect("a component");
        first.as_os_str().to_string_lossy().trim_end_matches(".rs").to_owned()
    };
    let mut out: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    let mut stack = vec![folder.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).expect("read_dir").flatten() {
            let path = entry.path();
            if path.is_dir() {
                stack.push(path);
                continue;
            }
            if path.extension().is_none_or(|e| e != "rs") {
                continue;
            }
            let module = module_of(&path);
            if module == "lib" || module == "main" {
                continue;
            }
            let source = without_comments(&std::fs::read_to_string(&path).expect("source"));
            let refs = out.entry(module.clone()).or_default();
            refs.extend(crate_references(&source).into_iter().filter(|r| *r != module));
            // A top-level module's file (`x.rs`, `x/mod.rs`) names its siblings as `super::y`
            // too: its parent is the crate's root.
            let top_level = path.parent() == Some(folder)
                || (path.file_name().is_some_and(|n| n == "mod.rs")
                    && path.parent().and_then(Path::parent) == Some(folder));
            if top_level {
                refs.extend(references_after(&source, "super::").into_iter().filter(|r| *r != module));
            }
        }
    }
    out
}

#[test]
fn imports_follow_the_module_order_of_architecture_md() {
    let text = std::fs::read_to_string(repo().join("ARCHITECTURE.md")).expect("ARCHITECTURE.md");
    let orders = orders(&text);
    assert!(orders.len() >= 3, "the module order block lost its crates: {orders:?}");
    let known = exceptions(&text);
    let mut problems = Vec::new();
    let mut seen = BTreeSet::new();
    for (folder, order) in &orders {
        let position = |m: &str| order.iter().position(|o| o == m);
        let refs = references(&repo().join(folder));
        for module in refs.keys() {
            if position(module).is_none() {
                problems.push(format!("{folder}: module `{module}` is not in the order"));
            }
        }
        for module in order {
            if !refs.contains_key(module) {
                problems.push(format!("{folder}: `{module}` is in the order but not in the crate"));
            }
        }
        for (module, targets) in &refs {
            let Some(at) = position(module) else { continue };
            for target in targets.iter().filter(|t| refs.contains_key(*t)) {
                let arrow = (folder.clone(), module.clone(), target.clone());
                if position(target).is_some_and(|t| t > at) {
                    if known.contains(&arrow) {
                        seen.insert(arrow);
                    } else {
                        problems.push(format!("{folder}: `{module}` -> `{target}` points back up the order"));
                    }
                }
            }
        }
    }
    for arrow in known.difference(&seen) {
        problems.push(format!(
            "{}: `{} -> {}` is listed as known but is gone: take it off the list",
            arrow.0, arrow.1, arrow.2
        ));
    }
    assert!(problems.is_empty(), "ARCHITECTURE.md's module order:\n{}", problems.join("\n"));
}

#[test]
fn references_inside_braces_are_found() {
    let source = "use crate::{a::{B, C}, d, e::f};\nlet x = crate::g::h();";
    let got: Vec<String> = crate_references(source).into_iter().collect();
    assert_eq!(got, ["a", "d", "e", "g"]);
    assert!(crate_references(&without_comments("// crate::x\nlet y = 1; // crate::z")).is_empty());
}

/// The short name ARCHITECTURE.md's crates table uses for the crate in `dir` (relative to
/// the workspace): `core` for `core-nostd/`, `camera` for `adapters/camera-c/`, else the
/// folder's name.
fn short_name(dir: &str) -> String {
    let last = dir.trim_end_matches('/').rsplit('/').next().unwrap_or(dir);
    match last {
        "core-nostd" => "core".to_owned(),
        "camera-c" => "camera".to_owned(),
        other => other.to_owned(),
    }
}

/// The crates table: for each crate's folder, the crates it may depend on (normal) and,
/// after `tests:` in brackets, those its tests may add.
fn allowed_edges(text: &str) -> BTreeMap<String, (BTreeSet<String>, BTreeSet<String>)> {
    let table = text.lines().skip_while(|l| l.trim() != "## Crates").take_while(|l| !l.starts_with("## Code map"));
    let mut out = BTreeMap::new();
    for line in table.filter(|l| l.starts_with("| `")) {
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        let (Some(path), Some(deps)) = (cells.get(2), cells.get(4)) else { continue };
        let names = |s: &str| -> BTreeSet<String> {
            s.split(',').filter_map(|w| w.split_whitespace().next()).map(|w| w.trim_matches('`').to_owned()).collect()
        };
        let (normal, tests) = match deps.split_once("(tests:") {
            Some((normal, tests)) => (names(normal), names(tests.trim_end_matches(')'))),
            None => (names(deps.split('(').next().unwrap_or(deps)), BTreeSet::new()),
        };
        for dir in path.split(',').map(|p| p.trim().trim_matches('`')) {
            out.insert(dir.trim_end_matches('/').to_owned(), (normal.clone(), tests.clone()));
        }
    }
    out
}

/// Every workspace crate depends only on the crates ARCHITECTURE.md's table allows it (the
/// Cargo manifests as `cargo metadata` reads them), and every crate is in the table.
#[test]
fn crates_depend_only_on_what_the_crates_table_allows() {
    let text = std::fs::read_to_string(repo().join("ARCHITECTURE.md")).expect("ARCHITECTURE.md");
    let allowed = allowed_edges(&text);
    assert!(allowed.len() >= 8, "the crates table lost its rows: {allowed:?}");
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_owned());
    let out = std::process::Command::new(cargo)
        .args(["metadata", "--format-version", "1", "--no-deps", "--offline"])
        .current_dir(repo())
        .output()
        .expect("cargo metadata");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let metadata: serde_json::Value = serde_json::from_slice(&out.stdout).expect("metadata JSON");
    let root = std::fs::canonicalize(repo()).expect("repo");
    let relative = |manifest: &str| -> String {
        let dir = Path::new(manifest).parent().expect("a manifest's folder");
        dir.strip_prefix(&root).unwrap_or(dir).to_string_lossy().into_owned()
    };
    let mut problems = Vec::new();
    let packages = metadata["packages"].as_array().expect("packages");
    for package in packages {
        let dir = relative(package["manifest_path"].as_str().expect("manifest_path"));
        let Some((normal, tests)) = allowed.get(&dir) else {
            problems.push(format!("{dir}: not in the crates table"));
            continue;
        };
        for dependency in package["dependencies"].as_array().expect("dependencies") {
            let Some(path) = dependency["path"].as_str() else { continue };
            let target = short_name(&Path::new(path).strip_prefix(&root).unwrap_or(Path::new(path)).to_string_lossy());
            let dev = dependency["kind"].as_str() == Some("dev");
            if !(normal.contains(&target) || dev && tests.contains(&target)) {
                problems.push(format!("{dir} depends on {target}{}", if dev { " (tests)" } else { "" }));
            }
        }
    }
    assert!(problems.is_empty(), "ARCHITECTURE.md's crates table:\n{}", problems.join("\n"));
}

/// The files and subfolders of each folder below a crate's source root, and which of their
/// siblings each refers to (`super::name` from a file of the folder, or the folder's full
/// `crate::` path from anywhere in it); the folder's own `mod.rs` is the parent, not a sibling.
fn sibling_references(src: &Path) -> BTreeMap<String, BTreeMap<String, BTreeSet<String>>> {
    let mut out = BTreeMap::new();
    let mut stack: Vec<PathBuf> =
        std::fs::read_dir(src).expect("read_dir").flatten().map(|e| e.path()).filter(|p| p.is_dir()).collect();
    while let Some(dir) = stack.pop() {
        let module_path = dir.strip_prefix(src).expect("inside").to_string_lossy().replace('/', "::");
        let mut siblings: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
        for entry in std::fs::read_dir(&dir).expect("read_dir").flatten() {
            let path = entry.path();
            let (name, files) = if path.is_dir() {
                stack.push(path.clone());
                let mut files = Vec::new();
                let mut inner = vec![path.clone()];
                while let Some(d) = inner.pop() {
                    for e in std::fs::read_dir(&d).expect("read_dir").flatten() {
                        let p = e.path();
                        if p.is_dir() {
                            inner.push(p);
                        } else if p.extension().is_some_and(|e| e == "rs") {
                            files.push(p);
                        }
                    }
                }
                (path.file_name().expect("name").to_string_lossy().into_owned(), files)
            } else if path.extension().is_some_and(|e| e == "rs") && path.file_stem().is_some_and(|s| s != "mod") {
                (path.file_stem().expect("stem").to_string_lossy().into_owned(), vec![path.clone()])
            } else {
                continue;
            };
            let refs = siblings.entry(name.clone()).or_default();
            for file in files {
                let source = without_comments(&std::fs::read_to_string(&file).expect("source"));
                refs.extend(references_after(&source, &format!("crate::{module_path}::")));
                // `super::` from a file directly in the folder (or a subfolder's `mod.rs`).
                let direct = file.parent() == Some(dir.as_path())
                    || (file.file_stem().is_some_and(|s| s == "mod")
                        && file.parent().and_then(Path::parent) == Some(dir.as_path()));
                if direct {
                    refs.extend(references_after(&source, "super::"));
                }
            }
            refs.remove(&name);
        }
        let names: BTreeSet<String> = siblings.keys().cloned().collect();
        for refs in siblings.values_mut() {
            refs.retain(|r| names.contains(r));
        }
        out.insert(dir.strip_prefix(src).expect("inside").display().to_string(), siblings);
    }
    out
}

/// A circle of `graph`, if it has one: the names around it.
fn circle(graph: &BTreeMap<String, BTreeSet<String>>) -> Option<Vec<String>> {
    fn visit(
        node: &str,
        graph: &BTreeMap<String, BTreeSet<String>>,
        path: &mut Vec<String>,
        done: &mut BTreeSet<String>,
    ) -> Option<Vec<String>> {
        if let Some(at) = path.iter().position(|p| p == node) {
            return Some(path[at..].to_vec());
        }
        if done.contains(node) {
            return None;
        }
        path.push(node.to_owned());
        for next in graph.get(node).into_iter().flatten() {
            if let Some(c) = visit(next, graph, path, done) {
                return Some(c);
            }
        }
        path.pop();
        done.insert(node.to_owned());
        None
    }
    let mut done = BTreeSet::new();
    graph.keys().find_map(|n| visit(n, graph, &mut Vec::new(), &mut done))
}

/// No files (or subfolders) of one folder refer to one another in a circle, in any crate
/// of the module order (issue #56: the one `sim/fidelity` had is gone; this keeps it so).
#[test]
fn no_folder_holds_a_circle() {
    let text = std::fs::read_to_string(repo().join("ARCHITECTURE.md")).expect("ARCHITECTURE.md");
    let mut problems = Vec::new();
    for folder in orders(&text).keys() {
        for (dir, siblings) in sibling_references(&repo().join(folder)) {
            if let Some(c) = circle(&siblings) {
                problems.push(format!("{folder}/{dir}: {} -> {}", c.join(" -> "), c[0]));
            }
        }
    }
    assert!(problems.is_empty(), "circles inside a folder:\n{}", problems.join("\n"));
}

#[test]
fn a_circle_is_found_and_a_chain_is_not() {
    let graph = |edges: &[(&str, &str)]| {
        let mut g: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
        for (a, b) in edges {
            g.entry((*a).to_owned()).or_default().insert((*b).to_owned());
            g.entry((*b).to_owned()).or_default();
        }
        g
    };
    assert_eq!(
        circle(&graph(&[("sweep", "summary"), ("summary", "plot"), ("plot", "sweep")])).map(|c| c.len()),
        Some(3)
    );
    assert_eq!(circle(&graph(&[("sweep", "rows"), ("summary", "rows"), ("plot", "rows")])), None);
    let source = "use super::{rows::Row, summary};\nlet x = super::super::finish::y;";
    assert_eq!(references_after(source, "super::").into_iter().collect::<Vec<_>>(), ["rows", "summary"]);
}

/// The library crates' source folders: everything below the binaries (the CLI, its argument
/// words, the examples) — what Python users and other programs call.
const LIBRARY_SOURCES: [&str; 10] = [
    "core-nostd/src",
    "adapters/linux/src",
    "adapters/can/src",
    "adapters/trajectory/src",
    "adapters/verify/src",
    "adapters/finish/src",
    "adapters/export/src",
    "adapters/sim/src",
    "adapters/python/src",
    "adapters/camera-c/src",
];

/// Strings a library writes into its outputs (not messages), which name the command that
/// made the file: `(file, the string's start)`.
const PROVENANCE: [(&str, &str); 1] = [("adapters/export/src/commonroad.rs", "<?xml version='1.0'")];

/// The string literals of `source` (outside comments and before its unit tests) that name a
/// command-line flag (`--word`).
fn flags_in_strings(source: &str) -> Vec<String> {
    let code = source.split("#[cfg(test)]\nmod tests").next().unwrap_or(source);
    let code = without_comments(code);
    let mut found = Vec::new();
    let mut chars = code.chars().peekable();
    let mut previous = ' ';
    while let Some(c) = chars.next() {
        // A character literal ('"') is not a string's start.
        if c == '"' && previous != '\'' {
            let mut literal = String::new();
            while let Some(d) = chars.next() {
                match d {
                    '\\' => {
                        chars.next();
                    }
                    '"' => break,
                    _ => literal.push(d),
                }
            }
            let names_a_flag = literal.match_indices("--").any(|(i, _)| {
                let before = literal[..i].chars().next_back().unwrap_or(' ');
                let after = literal[i + 2..].chars().next().unwrap_or(' ');
                !before.is_alphanumeric() && before != '-' && after.is_ascii_lowercase()
            });
            if names_a_flag {
                found.push(literal);
            }
            previous = '"';
        } else {
            previous = c;
        }
    }
    found
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("source folder").flatten() {
        let path = entry.path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// Issue #56: the libraries speak their own terms — a request's field is named by
/// `dash2sim_linux::Field`, and the command line maps it to its flag — so no library string
/// names a flag, whoever calls the library.
#[test]
fn no_library_string_names_a_command_line_flag() {
    let mut problems = Vec::new();
    for folder in LIBRARY_SOURCES {
        let mut files = Vec::new();
        rust_files(&repo().join(folder), &mut files);
        for path in files {
            let source = std::fs::read_to_string(&path).expect("source");
            let name = path.strip_prefix(repo()).unwrap_or(&path).display().to_string().replace("../", "");
            for literal in flags_in_strings(&source) {
                let known = PROVENANCE.iter().any(|(file, start)| name.ends_with(file) && literal.starts_with(start));
                if !known {
                    problems.push(format!("{name}: {literal:?}"));
                }
            }
        }
    }
    assert!(problems.is_empty(), "library strings naming a command-line flag:\n{}", problems.join("\n"));
}

#[test]
fn a_flag_in_a_string_is_found_and_one_in_a_comment_or_a_test_is_not() {
    let source = "// --map in a comment\nlet e = Error::invalid(\"--nuplan needs --map\");\n\
                  let s = \"a well-known -- dash\";\nlet c = '\"';\nlet t = \"x\\\"--not-this\";\n\
                  #[cfg(test)]\nmod tests {\n    const T: &str = \"--map\";\n}\n";
    assert_eq!(flags_in_strings(source), ["--nuplan needs --map"]);
}

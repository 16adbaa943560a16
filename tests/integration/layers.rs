//! The library's layering, checked on its source: each layer imports only the layers before
//! it (`docs/architecture.md`), and no two modules import each other, even through others.
//!
//! A reference counts wherever code names `crate::<module>`; comments do not count, so a
//! doc link may point anywhere. The layers hold for test code too; the cycle check reads
//! the library alone, since a test module is compiled only for its tests.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The layers in the order they may import each other: a module may name its own layer
/// and the ones before it.
const LAYERS: [&str; 13] = [
    "geometry",
    "config",
    "program",
    "post",
    "plan",
    "protocol",
    "log",
    "transport",
    "judge",
    "records",
    "telemetry",
    "opcua",
    "console",
];

/// Outside the data flow: the papers' geometry, which only the command line reaches.
const PAPERS: &str = "papers";

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The module path of a source file below `src/`: `plan/table.rs` → `["plan", "table"]`.
fn module_of(src: &Path, file: &Path) -> Vec<String> {
    let relative = file.strip_prefix(src).unwrap().with_extension("");
    let mut parts: Vec<String> = relative
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if parts.last().is_some_and(|p| p == "mod") {
        parts.pop();
    }
    parts
}

/// The source without comments: `//` to the end of a line (outside string literals,
/// which this source does not put `//` in before a path).
fn code_of(text: &str) -> String {
    text.lines()
        .map(|line| match line.find("//") {
            Some(at) => &line[..at],
            None => line,
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The `crate::a::b` paths a file names, as their first two segments (`["a", "b"]`, or
/// just `["a"]`), with grouped imports (`crate::{a, b::c}`) spelled out.
fn references(code: &str) -> BTreeSet<Vec<String>> {
    let mut found = BTreeSet::new();
    let mut rest = code;
    while let Some(at) = rest.find("crate::") {
        let before = rest[..at].chars().last();
        rest = &rest[at + "crate::".len()..];
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
            continue;
        }
        if let Some(group) = rest.strip_prefix('{') {
            let end = group.find('}').unwrap_or(group.len());
            for item in group[..end].split(',') {
                push_path(item.trim(), &mut found);
            }
        } else {
            push_path(rest, &mut found);
        }
    }
    found
}

fn push_path(text: &str, found: &mut BTreeSet<Vec<String>>) {
    let segments: Vec<String> = text
        .split("::")
        .map(|s| {
            s.chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect::<String>()
        })
        .take_while(|s| !s.is_empty() && s.chars().next().is_some_and(|c| c.is_lowercase()))
        .take(2)
        .collect();
    if !segments.is_empty() && segments[0] != "self" {
        found.insert(segments);
    }
}

/// A library file: its module path, what it names, and what its code outside test
/// modules names (empty for a file that is itself a test module).
struct File {
    module: Vec<String>,
    names: BTreeSet<Vec<String>>,
    library_names: BTreeSet<Vec<String>>,
}

/// The code before a file's inline `#[cfg(test)] mod …` block (which ends the file).
fn before_tests(code: &str) -> &str {
    let mut at = 0;
    for line in code.split_inclusive('\n') {
        if line.trim() == "#[cfg(test)]" && code[at + line.len()..].trim_start().contains(" {") {
            let next = code[at + line.len()..].trim_start();
            if next.starts_with("mod ") && next.lines().next().is_some_and(|l| l.ends_with('{')) {
                return &code[..at];
            }
        }
        at += line.len();
    }
    code
}

/// Modules declared `#[cfg(test)] mod name;` by their parent: test-only files.
fn test_modules(files: &[(Vec<String>, String)]) -> BTreeSet<Vec<String>> {
    let mut found = BTreeSet::new();
    for (module, code) in files {
        let lines: Vec<&str> = code.lines().map(str::trim).collect();
        for pair in lines.windows(2) {
            if pair[0] != "#[cfg(test)]" {
                continue;
            }
            let declared = pair[1]
                .trim_start_matches("pub(crate) ")
                .strip_prefix("mod ")
                .and_then(|rest| rest.strip_suffix(';'));
            if let Some(name) = declared {
                let mut child = module.clone();
                child.push(name.to_owned());
                found.insert(child);
            }
        }
    }
    found
}

/// Every library file.
fn library() -> Vec<File> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut paths = Vec::new();
    rust_files(&src, &mut paths);
    paths.sort();
    let files: Vec<(Vec<String>, String)> = paths
        .iter()
        .map(|f| {
            (
                module_of(&src, f),
                code_of(&std::fs::read_to_string(f).unwrap()),
            )
        })
        .filter(|(m, _)| m[0] != "bin" && m[0] != "main" && m[0] != "lib")
        .collect();
    let tests = test_modules(&files);
    files
        .iter()
        .map(|(module, code)| File {
            module: module.clone(),
            names: references(code),
            library_names: if tests.iter().any(|t| module.starts_with(t)) {
                BTreeSet::new()
            } else {
                references(before_tests(code))
            },
        })
        .collect()
}

fn rank(layer: &str) -> Option<usize> {
    LAYERS.iter().position(|l| *l == layer)
}

#[test]
fn each_layer_imports_only_the_layers_before_it() {
    let mut wrong = Vec::new();
    for File { module, names, .. } in library() {
        let layer = &module[0];
        for name in names {
            let target = &name[0];
            let allowed = if layer == PAPERS {
                target == PAPERS || target == LAYERS[0]
            } else {
                match (rank(layer), rank(target)) {
                    (Some(from), Some(to)) => to <= from,
                    _ => false,
                }
            };
            if !allowed {
                wrong.push(format!(
                    "{} names crate::{}",
                    module.join("::"),
                    name.join("::")
                ));
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "imports that run back up:\n{}",
        wrong.join("\n")
    );
}

#[test]
fn no_two_modules_import_each_other() {
    // The graph of second-level modules (`plan::table`, `protocol::grbl`, …): an edge for
    // every file of one that names the other.
    let mut edges: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for File {
        module,
        library_names,
        ..
    } in library()
    {
        let from = module
            .iter()
            .take(2)
            .cloned()
            .collect::<Vec<_>>()
            .join("::");
        for name in library_names {
            let to = name.join("::");
            if to != from && !from.starts_with(&format!("{to}::")) {
                edges.entry(from.clone()).or_default().insert(to);
            }
        }
    }
    // Depth-first search for a cycle, reporting its path.
    fn visit(
        node: &str,
        edges: &BTreeMap<String, BTreeSet<String>>,
        state: &mut BTreeMap<String, bool>,
        stack: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        match state.get(node) {
            Some(true) => {
                let start = stack.iter().position(|n| n == node).unwrap();
                let mut cycle = stack[start..].to_vec();
                cycle.push(node.to_owned());
                return Some(cycle);
            }
            Some(false) => return None,
            None => {}
        }
        state.insert(node.to_owned(), true);
        stack.push(node.to_owned());
        for next in edges.get(node).into_iter().flatten() {
            if let Some(cycle) = visit(next, edges, state, stack) {
                return Some(cycle);
            }
        }
        stack.pop();
        state.insert(node.to_owned(), false);
        None
    }
    let mut state = BTreeMap::new();
    for node in edges.keys() {
        let mut stack = Vec::new();
        if let Some(cycle) = visit(node, &edges, &mut state, &mut stack) {
            panic!("an import cycle: {}", cycle.join(" → "));
        }
    }
}

#[test]
fn the_checker_sees_grouped_and_plain_paths_and_knows_test_code() {
    let code = "use crate::{plan::table, config};\nlet x = crate::post::gcode::write(p);\n";
    let found: Vec<String> = references(code).into_iter().map(|p| p.join("::")).collect();
    assert_eq!(found, ["config", "plan::table", "post::gcode"]);
    assert!(references(&code_of("// see crate::judge")).is_empty());
    assert!(references("whirl_crate::judge").is_empty());
    let file = "use crate::a;\n#[cfg(test)]\nmod tests {\n    use crate::b;\n}\n";
    assert_eq!(before_tests(file), "use crate::a;\n");
    let parent = (
        vec!["x".to_owned()],
        "#[cfg(test)]\nmod tests;\nmod real;\n".to_owned(),
    );
    let found: Vec<String> = test_modules(&[parent])
        .into_iter()
        .map(|m| m.join("::"))
        .collect();
    assert_eq!(found, ["x::tests"]);
}

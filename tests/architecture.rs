//! The layering of docs/ARCHITECTURE.md, enforced: a module of `src/` may use only modules of
//! lower layers (and its own). Reads every `crate::` path in the library's sources.

use std::collections::BTreeSet;
use std::path::Path;

/// The library's top-level modules, lowest layer first; modules on one line share a layer and
/// may not use each other.
const LAYERS: &[&[&str]] = &[
    &["atomic", "num"],
    &["config"],
    &["world"],
    &["game"],
    &["engine"],
    &["policy"],
    &["eval"],
    &["train"],
    &["render"],
    &["ngsim", "sumo", "report"],
    &["batch"],
    &["exit"],
];

fn layer_of(module: &str) -> Option<usize> {
    LAYERS.iter().position(|layer| layer.contains(&module))
}

/// The top-level module a source file belongs to (`src/world/step.rs` -> `world`).
fn module_of(src: &Path, file: &Path) -> String {
    let rel = file.strip_prefix(src).expect("under src");
    let first = rel.components().next().expect("a component");
    first
        .as_os_str()
        .to_string_lossy()
        .trim_end_matches(".rs")
        .to_string()
}

/// Every top-level module named by a `crate::` path in `text`, outside comments. Grouped
/// imports (`use crate::{a::X, b::Y}`) name each module inside the braces.
fn crate_paths(text: &str) -> BTreeSet<String> {
    let mut found = BTreeSet::new();
    for line in text.lines() {
        let code = line.split("//").next().unwrap_or("");
        let mut rest = code;
        while let Some(at) = rest.find("crate::") {
            rest = &rest[at + "crate::".len()..];
            if let Some(group) = rest.strip_prefix('{') {
                let inner = group.split('}').next().unwrap_or("");
                for item in inner.split(',') {
                    let name: String = item
                        .trim()
                        .chars()
                        .take_while(|c| c.is_alphanumeric() || *c == '_')
                        .collect();
                    if !name.is_empty() {
                        found.insert(name);
                    }
                }
            } else {
                let name: String = rest
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                if !name.is_empty() {
                    found.insert(name);
                }
            }
        }
    }
    found
}

/// Edges `(from, to, file)` against the layering.
fn violations(src: &Path) -> Vec<String> {
    let mut bad = Vec::new();
    let mut stack = vec![src.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).expect("readable src") {
            let path = entry.expect("entry").path();
            if path.is_dir() {
                // src/cli is the binary's, above every layer of the library.
                if path != src.join("cli") {
                    stack.push(path);
                }
                continue;
            }
            if path.extension().is_none_or(|e| e != "rs") || path.parent() == Some(src) && is_root(&path) {
                continue;
            }
            let from = module_of(src, &path);
            let Some(from_layer) = layer_of(&from) else {
                bad.push(format!("{}: module `{from}` is in no layer", path.display()));
                continue;
            };
            let text = std::fs::read_to_string(&path).expect("readable file");
            for to in crate_paths(&text) {
                if to == from {
                    continue;
                }
                match layer_of(&to) {
                    Some(l) if l < from_layer => {}
                    Some(_) => bad.push(format!("{}: `{from}` uses `{to}`", path.display())),
                    None => {} // an item of the crate root, not a module
                }
            }
        }
    }
    bad.sort();
    bad
}

/// `lib.rs` and `main.rs` sit above the layers.
fn is_root(path: &Path) -> bool {
    matches!(
        path.file_name().and_then(|n| n.to_str()),
        Some("lib.rs" | "main.rs")
    )
}

#[test]
fn the_library_follows_its_layers() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let bad = violations(&src);
    assert!(
        bad.is_empty(),
        "edges against the layering of docs/ARCHITECTURE.md:\n{}",
        bad.join("\n")
    );
}

#[test]
fn every_top_level_module_has_a_layer() {
    let lib = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("src/lib.rs")).unwrap();
    let modules: Vec<&str> = lib
        .lines()
        .filter_map(|l| l.trim().strip_prefix("pub mod "))
        .map(|m| m.trim_end_matches(';'))
        .collect();
    assert!(modules.len() >= 12, "{modules:?}");
    for m in modules {
        assert!(
            layer_of(m).is_some(),
            "src/lib.rs module `{m}` is in no layer of LAYERS"
        );
    }
}

#[test]
fn an_edge_against_the_order_is_caught() {
    // A copy of src with one upward edge added: the world using the engine.
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let tmp = Path::new(env!("CARGO_TARGET_TMPDIR")).join("arch");
    copy_dir(&src, &tmp);
    let step = tmp.join("world/step.rs");
    let text = std::fs::read_to_string(&step).unwrap();
    std::fs::write(&step, format!("use crate::engine::outcome::EgoStats;\n{text}")).unwrap();
    // Grouped imports are read too: the game using the policy layer.
    let reward = tmp.join("game/reward.rs");
    let text = std::fs::read_to_string(&reward).unwrap();
    std::fs::write(
        &reward,
        format!("use crate::{{config::Config, policy::Mode}};\n{text}"),
    )
    .unwrap();
    let bad = violations(&tmp);
    std::fs::remove_dir_all(&tmp).unwrap();
    assert_eq!(bad.len(), 2, "{bad:?}");
    assert!(bad[0].ends_with("`game` uses `policy`"), "{bad:?}");
    assert!(bad[1].ends_with("`world` uses `engine`"), "{bad:?}");
}

#[test]
fn paths_are_read_from_code_not_comments() {
    let found = crate_paths(
        "use crate::world::step::advance; // crate::policy in a comment\n\
         /// [`crate::train`] in a doc comment\n\
         let x = crate::{game::reward, engine::rollout::Actor};",
    );
    let found: Vec<&str> = found.iter().map(String::as_str).collect();
    assert_eq!(found, ["engine", "game", "world"]);
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let path = entry.unwrap().path();
        let dest = to.join(path.file_name().unwrap());
        if path.is_dir() {
            copy_dir(&path, &dest);
        } else {
            std::fs::copy(&path, &dest).unwrap();
        }
    }
}

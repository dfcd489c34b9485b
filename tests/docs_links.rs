//! The documentation's relative links resolve: every `[text](path)` and `![alt](path)` in
//! README.md, the docs and the other READMEs names a file or folder of the repository (web
//! links and in-page anchors are not checked). And the licence files Cargo.toml's `license`
//! names are there.

use std::path::{Path, PathBuf};

/// The Markdown files a reader follows links from.
fn documents(root: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = [
        "README.md",
        "CHANGELOG.md",
        "sumo_nets/README.md",
        "policies/README.md",
    ]
    .iter()
    .map(|f| root.join(f))
    .collect();
    let mut todo = vec![root.join("docs")];
    while let Some(dir) = todo.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                todo.push(path);
            } else if path.extension().is_some_and(|e| e == "md") {
                files.push(path);
            }
        }
    }
    files
}

/// The targets of the inline links in `text`: what stands between `](` and the next `)`.
fn links(text: &str) -> Vec<&str> {
    text.match_indices("](")
        .filter_map(|(at, _)| {
            let rest = &text[at + 2..];
            let end = rest.find(')')?;
            Some(rest[..end].trim())
        })
        .filter(|l| !l.contains(char::is_whitespace))
        .collect()
}

#[test]
fn every_relative_link_in_the_docs_resolves() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut checked = 0;
    let mut broken = Vec::new();
    for doc in documents(root) {
        let text = std::fs::read_to_string(&doc).unwrap();
        for link in links(&text) {
            if link.starts_with("http://")
                || link.starts_with("https://")
                || link.starts_with('#')
                || link.starts_with("mailto:")
            {
                continue;
            }
            let file = link.split('#').next().unwrap_or(link);
            checked += 1;
            if !doc.parent().unwrap().join(file).exists() {
                broken.push(format!("{}: {link}", doc.strip_prefix(root).unwrap().display()));
            }
        }
    }
    assert!(checked > 0, "no relative link found: the parser misses them");
    assert!(broken.is_empty(), "broken links:\n{}", broken.join("\n"));
}

#[test]
fn the_link_parser_finds_inline_links_and_images() {
    let text =
        "see [the guide](docs/GUIDE.md#run) and ![a picture](docs/images/a.png), not (this) or [x] (y)";
    assert_eq!(links(text), ["docs/GUIDE.md#run", "docs/images/a.png"]);
}

#[test]
fn the_licences_cargo_toml_names_are_there() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let manifest = std::fs::read_to_string(root.join("Cargo.toml")).unwrap();
    assert!(manifest.contains("license = \"MIT OR Apache-2.0\""));
    let mit = std::fs::read_to_string(root.join("LICENSE-MIT")).unwrap();
    assert!(mit.contains("Permission is hereby granted, free of charge"));
    let apache = std::fs::read_to_string(root.join("LICENSE-APACHE")).unwrap();
    assert!(apache.contains("Apache License") && apache.contains("Version 2.0, January 2004"));
    assert!(root.join("CITATION.cff").is_file());
}

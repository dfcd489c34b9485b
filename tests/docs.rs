//! The documentation's results stay true: every results file describes the shipped policies
//! (`scripts/results.py` records their hash), README's results are those files', and README
//! stays short and undated. (`tests/docs_links.rs` checks the links.)

use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// `sha256sum FILES | sha256sum` over the sorted files the patterns match (relative to the
/// repository), as `scripts/results.py` records it.
fn inputs_hash(patterns: &[&str]) -> String {
    let mut files: Vec<String> = patterns
        .iter()
        .flat_map(|p| glob::glob(root().join(p).to_str().unwrap()).unwrap())
        .map(|f| {
            f.unwrap()
                .strip_prefix(root())
                .unwrap()
                .to_str()
                .unwrap()
                .to_string()
        })
        .collect();
    files.sort();
    files.dedup();
    assert!(!files.is_empty(), "no file matches {patterns:?}");
    let listing: String = files
        .iter()
        .map(|f| {
            format!(
                "{:x}  {f}\n",
                Sha256::digest(std::fs::read(root().join(f)).unwrap())
            )
        })
        .collect();
    format!("{:x}", Sha256::digest(listing.as_bytes()))
}

#[test]
fn the_inputs_hash_is_what_coreutils_computes() {
    // The same hash by coreutils, as scripts/results.py documents it.
    let out = std::process::Command::new("sh")
        .args(["-c", "sha256sum LICENSE-APACHE LICENSE-MIT | sha256sum"])
        .current_dir(root())
        .output()
        .unwrap();
    let expected = String::from_utf8(out.stdout).unwrap();
    let expected = expected.split_whitespace().next().unwrap();
    assert_eq!(inputs_hash(&["LICENSE-*"]), expected);
}

#[test]
fn every_results_file_describes_the_shipped_policies() {
    let pattern = root().join("docs/results/*.md");
    let files: Vec<PathBuf> = glob::glob(pattern.to_str().unwrap())
        .unwrap()
        .map(Result::unwrap)
        .collect();
    assert!(
        files.iter().any(|f| f.ends_with("summary.md")),
        "docs/results/summary.md is missing"
    );
    for file in files {
        let text = read(&file);
        let first = text.lines().next().unwrap_or_default();
        let field = |name: &str| {
            let start = first
                .find(name)
                .unwrap_or_else(|| panic!("{}: its first line records no `{name}`", file.display()))
                + name.len();
            first[start..]
                .split(';')
                .next()
                .unwrap()
                .trim_end_matches(" -->")
                .trim()
                .to_string()
        };
        let inputs = field("inputs:");
        let patterns: Vec<&str> = inputs.split_whitespace().collect();
        assert_eq!(
            field("sha256:"),
            inputs_hash(&patterns),
            "{} describes other files than {inputs}: regenerate it with scripts/results.py",
            file.display()
        );
    }
}

#[test]
fn readme_is_short_and_its_results_are_the_generated_ones() {
    let readme = read(&root().join("README.md"));
    let lines = readme.lines().count();
    assert!(lines <= 260, "README.md has {lines} lines");
    // No dated measurement: dates belong to CHANGELOG.md and docs/experiments.md.
    let dated = readme.as_bytes().windows(10).any(|w| {
        w[..4].iter().all(u8::is_ascii_digit)
            && w[4] == b'-'
            && w[5..7].iter().all(u8::is_ascii_digit)
            && w[7] == b'-'
            && w[8..].iter().all(u8::is_ascii_digit)
    });
    assert!(!dated, "README.md holds a date");
    let begin = "<!-- results: docs/results/summary.md -->\n";
    let start = readme.find(begin).expect("README.md has a results block") + begin.len();
    let end = start + readme[start..].find("<!-- /results -->").expect("the block ends");
    let summary = read(&root().join("docs/results/summary.md"));
    let table = summary.split_once('\n').unwrap().1;
    assert_eq!(
        &readme[start..end],
        table,
        "README's results are not docs/results/summary.md's"
    );
}

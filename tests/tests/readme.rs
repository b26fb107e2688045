//! The commands of the README and of docs/USAGE.md (its examples, run from the repository root)
//! leave nothing untracked behind: every file they write (with `--record`, `--junit`,
//! `--report`, `-o`) is ignored by `.gitignore`.

use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The files the README's shell examples write, relative to where they are run.
fn outputs(readme: &str) -> Vec<String> {
    let mut files = Vec::new();
    let mut in_shell = false;
    for line in readme.lines() {
        if line.starts_with("```") {
            in_shell = line == "```sh";
            continue;
        }
        if !in_shell {
            continue;
        }
        let command = line.split(" #").next().unwrap_or_default();
        let words: Vec<&str> = command.split_whitespace().collect();
        for pair in words.windows(2) {
            if ["--record", "--junit", "--report", "-o"].contains(&pair[0]) {
                files.push(pair[1].to_owned());
            }
        }
    }
    files
}

#[test]
fn every_file_the_readme_writes_is_ignored() {
    let ignore = std::fs::read_to_string(root().join(".gitignore")).unwrap();
    let ignored: Vec<&str> = ignore
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(str::trim)
        .collect();
    for (doc, at_least) in [("README.md", 2), ("docs/USAGE.md", 4)] {
        let text = std::fs::read_to_string(root().join(doc)).unwrap();
        let files = outputs(&text);
        assert!(files.len() >= at_least, "{doc}'s examples write files: {files:?}");
        for f in &files {
            assert!(
                ignored.contains(&format!("/{f}").as_str()),
                "{doc} writes {f}, which .gitignore does not ignore"
            );
        }
    }
}

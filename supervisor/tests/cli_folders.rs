//! `harvemu scenario` and `harvemu validate` given folders: every `.ron` file directly in one,
//! sorted by name; a built-in folder by its name or path from any directory; a folder without a
//! `.ron` file is exit code 2; a pattern the shell left as it was is expanded on disk, else
//! against the built-in files.

mod common;

use common::harvemu;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn scratch(tag: &str) -> PathBuf {
    common::scratch("cli-folders", tag)
}

/// Runs `harvemu` with `args` in `dir`.
fn harvemu_in(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_harvemu"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("run harvemu")
}

fn stdout(out: &Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A short scenario named `name` on the repository's harvester, its expectation `expect`.
fn scenario(name: &str, expect: &str) -> String {
    let config = common::root().join("configs/harvester.ron");
    format!(
        r#"Scenario(name: "{name}", config: "{}", duration_s: 2.0, seed: Some(5), expect: [{expect}])"#,
        config.display()
    )
}

/// The `.ron` files directly in the repository's configs/scenarios/conformance/, by name, sorted.
fn conformance_cases() -> Vec<String> {
    let dir = common::root().join("configs/scenarios/conformance");
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file() && p.extension().is_some_and(|x| x == "ron"))
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert!(names.len() > 1, "{names:?}");
    names
}

#[test]
fn a_folder_is_its_ron_files_in_name_order_without_hidden_files_or_sub_folders() {
    let dir = scratch("folder");
    std::fs::write(dir.join("b.ron"), scenario("second", "NoCrashes")).unwrap();
    std::fs::write(dir.join("a.ron"), scenario("first", "NoCrashes")).unwrap();
    // None of these may be read: each would be an error.
    std::fs::write(dir.join(".swap.ron"), "not RON").unwrap();
    std::fs::write(dir.join("notes.txt"), "not RON").unwrap();
    std::fs::create_dir(dir.join("bench")).unwrap();
    std::fs::write(dir.join("bench/node.ron"), "not RON").unwrap();

    let out = harvemu(&["validate", dir.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert_eq!(
        stdout(&out),
        format!(
            "{0}/a.ron: ok (scenario)\n{0}/b.ron: ok (scenario)\n",
            dir.display()
        )
    );

    let junit = dir.join("out.xml.tmp");
    let out = harvemu(&[
        "scenario",
        dir.to_str().unwrap(),
        "--junit",
        junit.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let text = stdout(&out);
    let headings: Vec<&str> = text.lines().filter(|l| !l.starts_with(' ')).collect();
    assert_eq!(headings.len(), 3, "{text}");
    assert!(
        headings[0].starts_with(&format!("first ({}/a.ron, seed 5", dir.display())),
        "{text}"
    );
    assert!(
        headings[1].starts_with(&format!("second ({}/b.ron, seed 5", dir.display())),
        "{text}"
    );
    assert_eq!(headings[2], "2 passed, 0 failed");
    let xml = std::fs::read_to_string(&junit).unwrap();
    assert!(xml.contains("tests=\"2\" failures=\"0\""), "{xml}");
    let first = xml.find(&format!("name=\"first ({}/a.ron)\"", dir.display()));
    let second = xml.find(&format!("name=\"second ({}/b.ron)\"", dir.display()));
    assert!(first.is_some() && first < second, "{xml}");

    // A folder and a file together: the folder's files in their place among the arguments.
    let c = dir.join("bench/c.ron");
    std::fs::write(&c, scenario("third", "NoCrashes")).unwrap();
    std::fs::remove_file(dir.join("bench/node.ron")).unwrap();
    let out = harvemu(&["validate", c.to_str().unwrap(), dir.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let text = stdout(&out);
    let files: Vec<&str> = text.lines().collect();
    assert_eq!(files.len(), 3, "{files:?}");
    assert!(files[0].starts_with(&format!("{}: ok", c.display())), "{files:?}");
    assert!(
        files[1].starts_with(&format!("{}/a.ron: ok", dir.display())),
        "{files:?}"
    );
}

#[test]
fn a_folder_without_ron_files_is_exit_2_naming_it() {
    let dir = scratch("empty");
    let folder = dir.join("nothing here");
    std::fs::create_dir_all(folder.join("sub")).unwrap();
    std::fs::write(folder.join("sub/a.ron"), scenario("deeper", "NoCrashes")).unwrap();
    std::fs::write(folder.join("readme.txt"), "").unwrap();
    for command in ["scenario", "validate"] {
        let out = harvemu(&[command, folder.to_str().unwrap()]);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{command}: {err}");
        assert!(
            err.contains(&format!(
                "{}: a folder with no .ron file directly in it",
                folder.display()
            )),
            "{command}: {err}"
        );
        assert!(out.stdout.is_empty(), "{command}: nothing ran");
    }
}

/// A pattern the shell left as it was (quoted, or matching nothing there) is expanded by
/// harvemu: on disk, else against the built-in files of its folder; matching nothing, it is
/// exit code 2 naming it and the folder to pass instead.
#[test]
fn a_pattern_the_shell_left_is_expanded_on_disk_else_built_in() {
    let dir = scratch("glob");
    // On disk: the matches in name order, hidden files left out.
    for name in ["b.ron", "a.ron", ".c.ron", "d.txt"] {
        std::fs::write(dir.join(name), "not read").unwrap();
    }
    let err = stderr(&harvemu_in(&dir, &["validate", "*.ron"]));
    let named: Vec<&str> = err
        .lines()
        .skip(1)
        .map(|l| l.trim().split(':').next().unwrap())
        .collect();
    assert_eq!(named, ["a.ron", "b.ron"], "{err}");
    assert!(err.starts_with("harvemu: error: 2 problems:\n"), "{err}");
    // Built in, from a directory with no configs/: every shipped scenario, in name order.
    let mut shipped: Vec<String> = std::fs::read_dir(common::root().join("configs/scenarios"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".ron"))
        .collect();
    shipped.sort();
    let out = harvemu_in(&dir, &["validate", "configs/scenarios/*.ron"]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let expected: String = shipped
        .iter()
        .map(|n| format!("configs/scenarios/{n} (built in): ok (scenario)\n"))
        .collect();
    assert_eq!(stdout(&out), expected);
    let out = harvemu_in(&dir, &["scenario", "configs/scenarios/b?s_off.ron"]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert!(
        stdout(&out).contains("configs/scenarios/bus_off.ron"),
        "{}",
        stdout(&out)
    );
    // Matching nothing anywhere: exit 2, nothing ran.
    for command in ["scenario", "validate"] {
        let out = harvemu_in(&dir, &[command, "configs/scenarios/zz*.ron"]);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{command}: {err}");
        assert!(
            err.contains("configs/scenarios/zz*.ron: no file matches this pattern, on disk or built in"),
            "{command}: {err}"
        );
        assert!(
            err.contains("configs/scenarios stands for every .ron file directly in it"),
            "{err}"
        );
        assert!(out.stdout.is_empty(), "{command}: nothing ran");
    }
}

/// From an empty directory `conformance` and `configs/scenarios/conformance` are the built-in
/// suite: its `.ron` files directly in the folder (not the bench's node files), in name order,
/// each read as the built-in copy. In the repository they are the files on disk.
#[test]
fn the_built_in_conformance_folder_runs_from_an_empty_directory() {
    let cases = conformance_cases();
    let dir = scratch("built-in");
    let expected: String = cases
        .iter()
        .map(|c| format!("configs/scenarios/conformance/{c} (built in): ok (scenario)\n"))
        .collect();
    for arg in ["conformance", "configs/scenarios/conformance"] {
        let out = harvemu_in(&dir, &["validate", arg]);
        assert_eq!(out.status.code(), Some(0), "{arg}: {}", stderr(&out));
        assert_eq!(stdout(&out), expected, "{arg}");
    }

    let out = harvemu_in(&dir, &["scenario", "conformance", "--junit", "j.xml"]);
    assert_eq!(out.status.code(), Some(0), "{}{}", stdout(&out), stderr(&out));
    let xml = std::fs::read_to_string(dir.join("j.xml")).unwrap();
    assert_eq!(xml.matches("<testcase ").count(), cases.len(), "{xml}");
    assert!(
        xml.contains(&format!(
            "<testsuite name=\"harvemu scenario\" tests=\"{}\" failures=\"0\"",
            cases.len()
        )),
        "{xml}"
    );
    for c in &cases {
        assert!(
            xml.contains(&format!(
                "<property name=\"file\" value=\"configs/scenarios/conformance/{c}\"/>"
            )),
            "{c}: {xml}"
        );
    }
    assert!(!xml.contains("bench/"), "{xml}");

    // In the repository the disk's files are read.
    let out = harvemu(&["validate", "conformance"]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert_eq!(stdout(&out), expected.replace(" (built in)", ""));
}

/// A folder on disk wins over the built-in one of the same name, as a file does.
#[test]
fn a_folder_on_disk_wins_over_the_built_in_one() {
    let dir = scratch("disk-wins");
    let mine = dir.join("configs/scenarios/conformance");
    std::fs::create_dir_all(&mine).unwrap();
    std::fs::write(mine.join("mine.ron"), scenario("mine", "NoCrashes")).unwrap();
    let out = harvemu_in(&dir, &["validate", "conformance"]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert_eq!(
        stdout(&out),
        "configs/scenarios/conformance/mine.ron: ok (scenario)\n"
    );
    // A scenario file of the name beats a folder of it: `bus_off` stays the built-in scenario.
    std::fs::create_dir_all(dir.join("configs/scenarios/bus_off")).unwrap();
    std::fs::write(
        dir.join("configs/scenarios/bus_off/other.ron"),
        scenario("other", "NoCrashes"),
    )
    .unwrap();
    let out = harvemu_in(&dir, &["scenario", "bus_off"]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert!(
        stdout(&out).starts_with("D2 bus off and back (configs/scenarios/bus_off.ron (built in)"),
        "{}",
        stdout(&out)
    );
}

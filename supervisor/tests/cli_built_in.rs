//! The configs built into `harvemu`: run from an empty directory, it behaves as in the
//! repository, whose configs/ it reads from disk there; `config export` writes the repository's
//! configs; a file on disk wins over the built-in one.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs `harvemu` with `args` in `dir`.
fn harvemu_in(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_harvemu"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("run harvemu")
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Every file under `dir` (names starting with a dot left out, as the build leaves them out),
/// by its path inside `dir`, sorted.
fn files_under(dir: &Path) -> Vec<(String, PathBuf)> {
    let mut found = Vec::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let path = e.unwrap().path();
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            if name.starts_with('.') {
                continue;
            }
            if path.is_dir() {
                todo.push(path);
            } else {
                let rel = path.strip_prefix(dir).unwrap().to_string_lossy().into_owned();
                found.push((rel, path));
            }
        }
    }
    found.sort();
    found
}

/// The same command, in the repository (configs/ on disk) and in an empty directory (the
/// built-in configs): the output file `out` must come out byte for byte the same.
fn same_output_in_both(tag: &str, args: &[&str], out: &str) {
    let empty = common::scratch("cli-built-in", &format!("{tag}-empty"));
    let outputs = common::scratch("cli-built-in", &format!("{tag}-out"));
    let mut written = Vec::new();
    for (place, dir) in [("repo", common::root()), ("empty", empty.clone())] {
        let file = outputs.join(format!("{place}-{out}"));
        let mut full: Vec<&str> = args.to_vec();
        full.extend([
            if out.ends_with(".dbc") { "-o" } else { "--record" },
            file.to_str().unwrap(),
        ]);
        let run = harvemu_in(&dir, &full);
        assert_eq!(run.status.code(), Some(0), "{place}: {args:?}: {}", stderr(&run));
        let text = format!("{}{}", stderr(&run), String::from_utf8_lossy(&run.stdout));
        // Where the config came from is said (dbc says nothing), and it is the built-in one
        // only where there is no configs/ on disk.
        let said = text.contains("(built in)");
        assert_eq!(
            said,
            place == "empty" && args[0] != "dbc",
            "{place}: {args:?}: {text}"
        );
        written.push(std::fs::read(&file).unwrap());
    }
    assert!(written[0].len() > 1000, "{args:?}: a real output");
    assert!(written[0] == written[1], "{args:?}: the outputs differ");
    assert_eq!(
        common::listing(&empty),
        Vec::<String>::new(),
        "nothing left in the empty directory"
    );
}

#[test]
fn run_from_an_empty_directory_records_the_same_trace() {
    same_output_in_both("run", &["run", "--fast", "--for", "5s"], "run.log");
}

#[test]
fn scenario_by_name_from_an_empty_directory_records_the_same_trace() {
    same_output_in_both("scenario", &["scenario", "bus_off"], "bus_off.log");
}

#[test]
fn soak_from_an_empty_directory_records_the_same_trace() {
    same_output_in_both("soak", &["soak", "--hours", "0.01"], "soak.log");
}

#[test]
fn dbc_from_an_empty_directory_is_the_same() {
    same_output_in_both("dbc", &["dbc"], "harvester.dbc");
}

#[test]
fn export_writes_the_repository_configs_byte_for_byte_and_keeps_what_is_there() {
    let dir = common::scratch("cli-built-in", "export");
    let out = harvemu_in(&dir, &["config", "export", "mine"]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let shipped = files_under(&common::root().join("configs"));
    let exported = files_under(&dir.join("mine"));
    let names = |f: &[(String, PathBuf)]| f.iter().map(|(n, _)| n.clone()).collect::<Vec<_>>();
    assert_eq!(names(&exported), names(&shipped));
    assert!(
        shipped.len() > 30,
        "every node, scenario and the soak: {}",
        shipped.len()
    );
    for ((name, a), (_, b)) in shipped.iter().zip(&exported) {
        assert!(
            std::fs::read(a).unwrap() == std::fs::read(b).unwrap(),
            "{name} differs"
        );
    }
    let listed = harvemu_in(&dir, &["config", "list"]);
    let listed: Vec<String> = String::from_utf8(listed.stdout)
        .unwrap()
        .lines()
        .map(|l| l.replacen("configs/", "", 1))
        .collect();
    assert_eq!(listed, names(&shipped));

    // One file already there refuses the whole export, and it is left as it was.
    let edited = dir.join("mine/nodes/d0.ron");
    std::fs::write(&edited, "// mine\n").unwrap();
    std::fs::remove_file(dir.join("mine/harvester.ron")).unwrap();
    let out = harvemu_in(&dir, &["config", "export", "mine"]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("--force"), "{}", stderr(&out));
    assert_eq!(std::fs::read_to_string(&edited).unwrap(), "// mine\n");
    assert!(!dir.join("mine/harvester.ron").exists(), "nothing written");
    let out = harvemu_in(&dir, &["config", "export", "mine", "--force"]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert!(
        std::fs::read(&edited).unwrap()
            == std::fs::read(common::root().join("configs/nodes/d0.ron")).unwrap()
    );
    assert!(dir.join("mine/harvester.ron").is_file());
}

#[test]
fn export_refuses_a_file_for_a_folder_and_says_when_it_cannot_write() {
    let dir = common::scratch("cli-built-in", "export-fail");
    std::fs::write(dir.join("plain"), "x").unwrap();
    let out = harvemu_in(&dir, &["config", "export", "plain"]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("plain: not a folder"), "{}", stderr(&out));
    let out = harvemu_in(&dir, &["config", "export"]);
    assert_eq!(out.status.code(), Some(2), "DIR is needed");

    // A full disk: the first file is over the file-size limit.
    let full = dir.join("full");
    let out = common::harvemu_limited(&["config", "export", full.to_str().unwrap()], 64);
    assert_eq!(out.status.code(), Some(3), "{}", stderr(&out));
    assert!(stderr(&out).contains("cannot write"), "{}", stderr(&out));
    // A file that leads to /dev/full, overwritten.
    let linked = dir.join("linked");
    std::fs::create_dir(&linked).unwrap();
    std::os::unix::fs::symlink("/dev/full", linked.join("README.md")).unwrap();
    let out = harvemu_in(&dir, &["config", "export", "linked", "--force"]);
    assert_eq!(out.status.code(), Some(3), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("cannot write linked/README.md"),
        "{}",
        stderr(&out)
    );
}

/// Runs `harvemu run --fast --for 1s` with `args` in `dir` and gives its startup line.
fn startup(dir: &Path, args: &[&str]) -> String {
    let mut full = vec!["run", "--fast", "--for", "1s"];
    full.extend(args);
    let out = harvemu_in(dir, &full);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    stderr(&out).lines().next().unwrap_or_default().to_string()
}

#[test]
fn the_command_line_beats_the_working_directory_which_beats_the_built_in() {
    let dir = common::scratch("cli-built-in", "precedence");
    let line = startup(&dir, &[]);
    assert_eq!(
        line,
        "harvemu: 4MZ-6A (21 nodes) from configs/harvester.ron (built in), seed 2011"
    );
    // It fits a terminal of 80 columns.
    assert!(line.chars().count() <= 80, "{line}");

    // A stray node script in the working directory does not leak into the built-in harvester.
    std::fs::create_dir_all(dir.join("configs/nodes")).unwrap();
    std::fs::write(dir.join("configs/nodes/d0.ron"), "not a script").unwrap();
    assert!(startup(&dir, &[]).contains("(built in)"));

    // configs/harvester.ron in the working directory wins, with its own node scripts.
    let out = harvemu_in(&dir, &["config", "export", "configs", "--force"]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let path = dir.join("configs/harvester.ron");
    let text = std::fs::read_to_string(&path).unwrap();
    let mine = text
        .replacen("name: \"4MZ-6A\"", "name: \"Mine\"", 1)
        .replacen("\"nodes/e0.ron\",", "", 1);
    assert_ne!(mine, text, "the edit took");
    std::fs::write(&path, mine).unwrap();
    assert!(startup(&dir, &[]).contains("Mine (20 nodes) from configs/harvester.ron, seed"));

    // A config on the command line wins over both.
    std::fs::write(
        dir.join("other.ron"),
        text.replacen("name: \"4MZ-6A\"", "name: \"Other\"", 1)
            .replace("\"nodes/", "\"configs/nodes/"),
    )
    .unwrap();
    assert!(startup(&dir, &["other.ron"]).contains("Other (21 nodes) from other.ron, seed"));

    // A file that is there but broken is an error, never a quiet switch to the built-in one.
    std::fs::write(&path, "(").unwrap();
    let out = harvemu_in(&dir, &["run", "--fast", "--for", "1s"]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("configs/harvester.ron:1:"),
        "{}",
        stderr(&out)
    );
    assert!(!stderr(&out).contains("built in"), "{}", stderr(&out));
}

#[test]
fn unknown_names_and_validate_say_where_they_looked() {
    let dir = common::scratch("cli-built-in", "names");
    let out = harvemu_in(&dir, &["scenario", "bus_of"]);
    assert_eq!(out.status.code(), Some(2));
    let err = stderr(&out);
    assert!(
        err.contains(
            "configs/scenarios/bus_of.ron: no such file in the working directory, and none built in"
        ),
        "{err}"
    );
    assert_eq!(err.lines().count(), 1, "{err}");
    let out = harvemu_in(
        &dir,
        &["validate", "configs/harvester.ron", "configs/scenarios/crash.ron"],
    );
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert_eq!(
        String::from_utf8(out.stdout).unwrap(),
        "configs/harvester.ron (built in): ok (harvester config)\nconfigs/scenarios/crash.ron (built in): ok (scenario)\n"
    );
}

#[test]
fn a_built_in_scenario_is_reported_by_a_path_that_finds_it_again() {
    let dir = common::scratch("cli-built-in", "junit");
    let out = harvemu_in(&dir, &["scenario", "bus_off", "--junit", "j.xml"]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let stdout = String::from_utf8(out.stdout).unwrap();
    assert!(
        stdout.starts_with("D2 bus off and back (configs/scenarios/bus_off.ron (built in), seed "),
        "{stdout}"
    );
    // JUnit's file (and a failure's command) is the path, which reads the built-in file again.
    let junit = std::fs::read_to_string(dir.join("j.xml")).unwrap();
    assert!(
        junit.contains("<property name=\"file\" value=\"configs/scenarios/bus_off.ron\"/>"),
        "{junit}"
    );
}

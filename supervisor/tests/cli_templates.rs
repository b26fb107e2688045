//! `harvemu validate` and `run` on node scripts made from templates: the shipped instances and
//! templates pass, and bad ones give exit code 2 naming the file and the parameter.

mod common;

use common::{harvemu, root, scratch};
use std::path::Path;

fn stdout(out: &std::process::Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn stderr(out: &std::process::Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn shipped_instances_and_templates_validate() {
    let out = harvemu(&[
        "validate",
        "configs/nodes/d2.ron",
        "configs/nodes/b4.ron",
        "configs/nodes/templates/flow_sensor.ron",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(
        stdout(&out),
        "configs/nodes/d2.ron: ok (node script from a template)\n\
         configs/nodes/b4.ron: ok (node script from a template)\n\
         configs/nodes/templates/flow_sensor.ron: ok (node script template)\n"
    );
}

/// D2's instance file with `edit` applied, written with a copy of the templates into `dir`.
fn d2(dir: &Path, edit: impl Fn(String) -> String) -> String {
    common::copy_dir(&root().join("configs/nodes/templates"), &dir.join("templates"));
    let text = std::fs::read_to_string(root().join("configs/nodes/d2.ron")).unwrap();
    let path = dir.join("d2.ron");
    std::fs::write(&path, edit(text)).unwrap();
    path.display().to_string()
}

#[test]
fn an_unknown_and_a_missing_parameter_give_exit_2() {
    let dir = scratch("cli-templates", "params");
    let file = d2(&dir, |t| t.replace(r#""row": "row3""#, r#""rows": "row3""#));
    let template = dir.join("templates/flow_sensor.ron").display().to_string();
    for args in [
        vec!["validate", file.as_str()],
        vec!["validate", "configs/harvester.ron", file.as_str()],
    ] {
        let out = harvemu(&args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = stderr(&out);
        for needle in [
            format!(
                "{file}: params.rows: unknown parameter: {template} takes address, boot_delay_ms, canidt, name, phase_ms, row"
            ),
            format!(
                "{file}: params: missing parameter 'row' (the plant's prefix for the row's signals (\"row1\"))"
            ),
        ] {
            assert!(err.contains(&needle), "{args:?}: missing {needle} in:\n{err}");
        }
    }
    // A harvester that names the instance is refused before anything runs.
    let config = dir.join("harvester.ron");
    let text = std::fs::read_to_string(root().join("configs/harvester.ron"))
        .unwrap()
        .replace(
            "\"nodes/",
            &format!("\"{}/nodes/", root().join("configs").display()),
        )
        .replace(
            &format!("{}/nodes/d2.ron", root().join("configs").display()),
            &file,
        );
    std::fs::write(&config, text).unwrap();
    let log = dir.join("never.log");
    let out = harvemu(&[
        "run",
        config.to_str().unwrap(),
        "--fast",
        "--for",
        "1s",
        "--record",
        log.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains(&format!("{file}: params.rows: unknown parameter")));
    assert!(!log.exists(), "nothing was started");
}

#[test]
fn a_bad_template_gives_exit_2_alone_and_through_its_instance() {
    let dir = scratch("cli-templates", "template");
    let instance = d2(&dir, |t| t);
    let template = dir.join("templates/flow_sensor.ron");
    let text = std::fs::read_to_string(&template).unwrap();
    // The reference group's phase becomes a parameter nobody declared.
    let bad = text.replacen(
        r#"phase_ms: "${phase_ms}"),
                states: ["calibrating""#,
        r#"phase_ms: "${ref_phase}"),
                states: ["calibrating""#,
        1,
    );
    assert_ne!(bad, text);
    std::fs::write(&template, &bad).unwrap();
    let line = 1 + bad.lines().position(|l| l.contains("${ref_phase}")).unwrap();
    let col = 1 + bad.lines().nth(line - 1).unwrap().find("${ref_phase}").unwrap();
    let t = template.display().to_string();
    let needle = format!(
        "{t}:{line}:{col}: placeholder 'ref_phase' is not a declared parameter (params: address, boot_delay_ms, canidt, name, phase_ms, row)"
    );
    for target in [t.as_str(), instance.as_str()] {
        let out = harvemu(&["validate", target]);
        assert_eq!(out.status.code(), Some(2), "{target}");
        assert!(stderr(&out).contains(&needle), "{target}: {}", stderr(&out));
    }
}

#[test]
fn an_instance_of_itself_gives_exit_2() {
    let dir = scratch("cli-templates", "self");
    let file = d2(&dir, |t| t.replace("templates/flow_sensor.ron", "d2.ron"));
    let out = harvemu(&["validate", &file]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        stderr(&out).contains(&format!(
            "{file}: template: {file} is an instance, not a Template: templates do not nest"
        )),
        "{}",
        stderr(&out)
    );
}

//! Templates and their instances (`nodes::script::expand`, reached through `load`): what an
//! expansion makes, and every way a template or an instance can be wrong.

use nodes::environment::PlantSignals;
use nodes::script::{Expr, When, check_template, disk, load, top_name};
use nodes::{Error, Problem};
use std::path::{Path, PathBuf};

/// A template of B1's script: four parameters, used as whole values and inside strings. Line 5
/// is `address: "${address}",`; line 13 holds `${signal}`; the comment's `${` is not scanned.
const TEMPLATE: &str = r#"// a comment that mentions ${not_a_param}
Template(
    params: {"address": "the address", "name": "the name", "signal": "a prefix", "phase": "ms"},
    script: NodeScript(
        address: "${address}",
        name: "${name}",
        kind: Parameter,
        filter: Atmel(canidt: "28 05 8F A8", canidm: "FF FF FF FD", ide: true),
        boot_delay_ms: 85,
        states: [(name: "boot", code: 0), (name: "running", code: 1)],
        initial: "running",
        messages: [(name: "parameters", frames: [(message: "param.engine",
            fields: {"engine_rpm": Signal("${signal}.rpm")})],
            when: Periodic(period_ms: 100, phase_ms: "${phase}"))],
    ),
)
"#;

const PARAMS: &str = r#""address": 0xB1, "name": "B1", "signal": "engine", "phase": 12"#;

/// A fresh directory holding `t.ron` (the template) and `i.ron` (an instance of it).
fn setup(tag: &str, template: &str, params: &str) -> (PathBuf, PathBuf) {
    let dir = std::env::temp_dir().join(format!("harvemu-templates-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("t.ron"), template).unwrap();
    let instance = dir.join("i.ron");
    std::fs::write(
        &instance,
        format!("// B1\nInstance(template: \"t.ron\", params: {{{params}}})\n"),
    )
    .unwrap();
    (dir, instance)
}

fn problems(path: &Path) -> Vec<Problem> {
    match load(path, &PlantSignals) {
        Err(Error::Invalid(p)) => p,
        other => panic!("expected problems, got {other:?}"),
    }
}

fn file(p: &Path) -> String {
    p.display().to_string()
}

#[test]
fn an_instance_fills_whole_values_and_parts_of_strings() {
    let (_, instance) = setup("good", TEMPLATE, PARAMS);
    let s = load(&instance, &PlantSignals).unwrap();
    assert_eq!(s.address, 0xB1);
    assert_eq!(s.name, "B1");
    let m = &s.messages[0];
    assert_eq!(
        m.frames[0].fields.get("engine_rpm"),
        Some(&Expr::Signal("engine.rpm".into()))
    );
    assert!(matches!(
        m.when,
        When::Periodic {
            period_ms: 100,
            phase_ms: 12
        }
    ));
}

#[test]
fn a_whole_value_may_be_a_map_of_expressions() {
    let template = TEMPLATE.replace(
        r#"fields: {"engine_rpm": Signal("${signal}.rpm")}"#,
        r#"fields: "${fields}""#,
    );
    let template = template.replace(r#""signal": "a prefix""#, r#""fields": "the fields""#);
    let (_, instance) = setup(
        "map",
        &template,
        r#""address": 0xB1, "name": "B1", "phase": 12,
           "fields": {"engine_rpm": Scaled(Signal("engine.rpm"), 2.0, 0.0)}"#,
    );
    let s = load(&instance, &PlantSignals).unwrap();
    assert_eq!(
        s.messages[0].frames[0].fields.get("engine_rpm"),
        Some(&Expr::Scaled(
            Box::new(Expr::Signal("engine.rpm".into())),
            2.0,
            0.0
        ))
    );
}

#[test]
fn unknown_and_missing_parameters_are_both_named() {
    let (dir, instance) = setup(
        "params",
        TEMPLATE,
        r#""address": 0xB1, "name": "B1", "signal": "engine", "phse": 12"#,
    );
    let p = problems(&instance);
    let t = file(&dir.join("t.ron"));
    let i = file(&instance);
    let said: Vec<String> = p.iter().map(ToString::to_string).collect();
    assert_eq!(
        said,
        [
            format!("{i}: params.phse: unknown parameter: {t} takes address, name, phase, signal"),
            format!("{i}: params: missing parameter 'phase' (ms)"),
        ]
    );
}

#[test]
fn unused_and_undeclared_parameters_are_template_problems() {
    let template = TEMPLATE
        .replace(r#""phase": "ms""#, r#""phase": "ms", "spare": "never used""#)
        .replace(r#"Signal("${signal}.rpm")"#, r#"Signal("${sig}.rpm")"#);
    let (dir, instance) = setup("unused", &template, PARAMS);
    let t = file(&dir.join("t.ron"));
    // `${sig}` opens at line 13, column 44 (counted in the template above).
    let line = template.lines().nth(12).unwrap();
    assert_eq!(line.find("${sig}"), Some(43));
    let expected = [
        format!(
            "{t}:13:44: placeholder 'sig' is not a declared parameter (params: address, name, phase, signal, spare)"
        ),
        format!("{t}: params.signal: unused parameter: the script never uses it"),
        format!("{t}: params.spare: unused parameter: the script never uses it"),
    ];
    let said: Vec<String> = problems(&instance).iter().map(ToString::to_string).collect();
    assert_eq!(said, expected);
    // `harvemu validate` checks a template alone the same way.
    let (file, text) = disk(&dir.join("t.ron")).unwrap();
    let Err(Error::Invalid(alone)) = check_template(&file, &text) else {
        panic!("the template has problems");
    };
    let alone: Vec<String> = alone.iter().map(ToString::to_string).collect();
    assert_eq!(alone, expected);
    let (dir, _) = setup("good-alone", TEMPLATE, PARAMS);
    let (file, text) = disk(&dir.join("t.ron")).unwrap();
    check_template(&file, &text).unwrap();
}

#[test]
fn a_dollar_brace_that_is_no_placeholder_is_refused_where_it_is() {
    let template = TEMPLATE.replace(r#"name: "${name}""#, r#"name: "${name} ${ 2""#);
    let (dir, instance) = setup("malformed", &template, PARAMS);
    let p = problems(&instance);
    assert_eq!(p.len(), 1, "{p:?}");
    assert_eq!(p[0].file, file(&dir.join("t.ron")));
    // Line 6 is `        name: "${name} ${ 2",`: the second `${` is at column 24.
    assert_eq!(p[0].position, Some((6, 24)));
    assert!(p[0].message.starts_with("`${` starts no placeholder"), "{p:?}");
}

#[test]
fn templates_do_not_nest_and_an_instance_cannot_name_itself() {
    let (dir, instance) = setup("nest", TEMPLATE, PARAMS);
    let i = file(&instance);
    // An instance of an instance, and an instance of itself.
    for (name, target) in [("outer.ron", "i.ron"), ("self.ron", "self.ron")] {
        let path = dir.join(name);
        std::fs::write(
            &path,
            format!("Instance(template: {target:?}, params: {{{PARAMS}}})"),
        )
        .unwrap();
        let said: Vec<String> = problems(&path).iter().map(ToString::to_string).collect();
        let target = file(&dir.join(target));
        assert_eq!(
            said,
            [format!(
                "{}: template: {target} is an instance, not a Template: templates do not nest",
                file(&path)
            )]
        );
    }
    // A plain script is not a template either.
    let plain = dir.join("plain.ron");
    std::fs::write(&plain, "NodeScript(address: 0xB1)").unwrap();
    std::fs::write(
        &instance,
        format!("Instance(template: \"plain.ron\", params: {{{PARAMS}}})"),
    )
    .unwrap();
    let said: Vec<String> = problems(&instance).iter().map(ToString::to_string).collect();
    assert_eq!(
        said,
        [format!(
            "{i}: template: {} is a 'NodeScript', not a Template",
            file(&plain)
        )]
    );
}

#[test]
fn syntax_errors_are_placed_in_the_template_or_at_the_parameter() {
    // A wrong value: a string where the address goes.
    let (_, instance) = setup(
        "wrong-value",
        TEMPLATE,
        r#""address": "B1", "name": "B1", "signal": "engine", "phase": 12"#,
    );
    let p = problems(&instance);
    assert_eq!(p.len(), 1, "{p:?}");
    assert_eq!(
        (p[0].file.as_str(), p[0].position, p[0].field.as_deref()),
        (file(&instance).as_str(), None, Some("params.address"))
    );
    // Mistakes in the template, on a line after a substitution that changed its length: they
    // are reported at their line and column in the template, not in the expansion. A syntax
    // error is found before any expansion; a value of the wrong type only in the expansion.
    for (wrong, token, expanding) in [
        ("boot_delay_ms: 85 86,", "86", false),
        (r#"boot_delay_ms: "85","#, r#""85""#, true),
    ] {
        let template = TEMPLATE.replace("boot_delay_ms: 85,", wrong);
        let (dir, instance) = setup("wrong-template", &template, PARAMS);
        let p = problems(&instance);
        assert_eq!(p.len(), 1, "{p:?}");
        assert_eq!(p[0].file, file(&dir.join("t.ron")));
        let line = template.lines().nth(8).unwrap();
        assert!(line.contains(wrong));
        let col = line.find(token).unwrap() + 1;
        assert_eq!(p[0].position, Some((9, col)), "{p:?}");
        assert_eq!(
            p[0].message
                .ends_with(&format!("(expanding {})", file(&instance))),
            expanding,
            "{p:?}"
        );
    }
}

#[test]
fn a_value_used_inside_a_string_must_be_a_string_or_a_number() {
    let (_, instance) = setup(
        "inline",
        TEMPLATE,
        r#""address": 0xB1, "name": "B1", "signal": ["engine"], "phase": 12"#,
    );
    let said: Vec<String> = problems(&instance).iter().map(ToString::to_string).collect();
    assert_eq!(
        said,
        [format!(
            "{}: params.signal: 'signal' is used inside a string of {}, so its value must be a string or a number",
            file(&instance),
            file(&instance.with_file_name("t.ron"))
        )]
    );
}

#[test]
fn the_script_made_is_validated_and_its_problems_name_the_instance() {
    let (_, instance) = setup(
        "invalid",
        TEMPLATE,
        r#""address": 0xB1, "name": "B1", "signal": "engin", "phase": 12"#,
    );
    let said: Vec<String> = problems(&instance).iter().map(ToString::to_string).collect();
    assert_eq!(
        said,
        [format!(
            "{}: node B1: messages[0] (parameters).frames[0].fields.engine_rpm: unknown plant signal 'engin.rpm'",
            file(&instance)
        )]
    );
}

#[test]
fn the_size_limit_holds_for_the_template_and_for_the_expansion() {
    let limit = nodes::file::MAX_FILE as usize;
    let pad = |text: &str, len: usize| format!("{text}//{}\n", "p".repeat(len - text.len() - 3));
    let (dir, instance) = setup("limit", &pad(TEMPLATE, limit), PARAMS);
    load(&instance, &PlantSignals).unwrap();
    std::fs::write(dir.join("t.ron"), pad(TEMPLATE, limit + 1)).unwrap();
    let said: Vec<String> = problems(&instance).iter().map(ToString::to_string).collect();
    assert_eq!(
        said,
        [format!(
            "{}: template: {}: larger than 1 MiB (1048576 bytes), the limit for an input file",
            file(&instance),
            file(&dir.join("t.ron"))
        )]
    );
    // A small template whose name appears twice, given a value of 600 000 characters.
    std::fs::write(
        dir.join("t.ron"),
        TEMPLATE.replace(
            r#"boot_delay_ms: 85,"#,
            r#"boot_delay_ms: 85, vars: {"${name}": 1.0},"#,
        ),
    )
    .unwrap();
    let long = format!(
        r#""address": 0xB1, "name": "{}", "signal": "engine", "phase": 12"#,
        "N".repeat(600_000)
    );
    std::fs::write(
        &instance,
        format!("Instance(template: \"t.ron\", params: {{{long}}})"),
    )
    .unwrap();
    let said: Vec<String> = problems(&instance).iter().map(ToString::to_string).collect();
    assert_eq!(
        said,
        [format!(
            "{}: template: {} expands to more than 1048576 bytes",
            file(&instance),
            file(&dir.join("t.ron"))
        )]
    );
}

#[test]
fn the_top_name_skips_comments() {
    assert_eq!(top_name("// x\n/* y /* z */ */ Instance(a: 1)"), Some("Instance"));
    assert_eq!(top_name("  NodeScript("), Some("NodeScript"));
    assert_eq!(top_name("(a: 1)"), None);
    assert_eq!(top_name(""), None);
}

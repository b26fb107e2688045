//! Numbers and names that would break a run: refused by validation, and harmless at run time
//! for a script that never went through it.

use super::*;
use proptest::prelude::*;

/// B1's script with its one field bound to `e`.
fn b1_with(e: Expr) -> NodeScript {
    let mut script = parse("test.ron", B1).unwrap();
    script.messages[0].frames[0].fields.insert("engine_rpm".into(), e);
    script
}

fn rpm() -> Box<Expr> {
    Box::new(Expr::Signal("engine.rpm".into()))
}

/// Runs a script, validated or not, from power-on at 500 ms to 1 s with engine.rpm at `rpm`.
fn run_unchecked(script: NodeScript, rpm: f64) -> (Vec<Frame>, ScriptedNode) {
    let fake = Rc::new(RefCell::new(Fake::default()));
    fake.borrow_mut().values.insert("engine.rpm".into(), rpm);
    let env: SharedEnv = fake;
    let mut n = ScriptedNode::new(script, env, BusTime::from_millis(500), 1);
    let sent = drive(&mut n, BusTime::from_millis(1000), &[]);
    (sent.into_iter().map(|(_, f)| f).collect(), n)
}

fn problems_with(e: Expr) -> Vec<String> {
    problems_of(&b1_with(e))
}

const FIELD: &str = "test.ron: node B1: messages[0] (p).frames[0].fields.engine_rpm: ";

#[test]
fn a_clamp_with_an_empty_or_nan_range_is_refused() {
    let inverted = problems_with(Expr::Clamp(rpm(), 5.0, 1.0));
    assert_eq!(inverted, [format!("{FIELD}Clamp min 5 is above its max 1")]);
    let nan = problems_with(Expr::Clamp(rpm(), f64::NAN, 1.0));
    assert_eq!(nan, [format!("{FIELD}Clamp min is NaN, not a finite number")]);
    let inf = problems_with(Expr::Clamp(rpm(), 0.0, f64::INFINITY));
    assert_eq!(inf, [format!("{FIELD}Clamp max is inf, not a finite number")]);
    assert!(problems_with(Expr::Clamp(rpm(), 1.0, 1.0)).is_empty());
}

#[test]
fn gains_offsets_and_steps_must_be_finite() {
    assert_eq!(
        problems_with(Expr::Scaled(rpm(), f64::NAN, 0.0)),
        [format!("{FIELD}Scaled gain is NaN, not a finite number")]
    );
    assert_eq!(
        problems_with(Expr::Scaled(rpm(), 1.0, f64::NEG_INFINITY)),
        [format!("{FIELD}Scaled offset is -inf, not a finite number")]
    );
    assert_eq!(
        problems_with(Expr::Quantize(rpm(), f64::INFINITY)),
        [format!(
            "{FIELD}Quantize step inf is not a positive finite number"
        )]
    );
    // Nested: the inner expression is checked too.
    let nested = Expr::Clamp(Box::new(Expr::Scaled(rpm(), f64::NAN, 0.0)), 0.0, 10.0);
    assert_eq!(
        problems_with(nested),
        [format!("{FIELD}Scaled gain is NaN, not a finite number")]
    );
}

#[test]
fn the_text_forms_of_nan_and_infinity_are_refused_too() {
    let text = B1.replace(
        r#"Signal("engine.rpm")"#,
        r#"Clamp(Scaled(Signal("engine.rpm"), NaN, inf), 3.0, 1.0)"#,
    );
    let script = parse("test.ron", &text).unwrap();
    let problems = problems_of(&script);
    assert_eq!(problems.len(), 3, "{problems:?}");
}

#[test]
fn variables_matches_and_faults_must_be_finite() {
    let text = B1.replace(
        "initial: \"running\",",
        r#"initial: "running", vars: {"x": inf},
        reactions: [], faults: [(signal: "engine.rpm", fault: Offset(NaN)), (signal: "engine.rpm", fault: Noise(-1.0))],"#,
    );
    let problems = problems_of(&parse("test.ron", &text).unwrap());
    let expect = [
        "test.ron: node B1: vars.x: the initial value is inf, not a finite number",
        "test.ron: node B1: faults[0].fault: Offset(NaN): not a finite number",
        "test.ron: node B1: faults[1].fault: Noise(-1): a standard deviation is not negative",
    ];
    assert_eq!(problems, expect);
    let mut script = parse("test.ron", E0).unwrap();
    script.reactions[0].when.insert("mode".into(), f64::NAN);
    let problems = problems_of(&script);
    assert!(
        problems.iter().any(|p| p.ends_with(
            "reactions[0] (speed.mode).when.mode: the value to match is NaN, not a finite number"
        )),
        "{problems:?}"
    );
}

#[test]
fn control_characters_and_spaces_in_names_are_refused() {
    let mut script = parse("test.ron", B1).unwrap();
    script.name = "B\u{0}1".into();
    script.states[1].name = "run\nning".into();
    script.initial = script.states[1].name.clone();
    let problems = problems_of(&script);
    assert_eq!(
        problems,
        [
            "test.ron: node B\\01: name: \"B\\01\" holds the control character '\\0'",
            "test.ron: node B\\01: states[1].name: \"run\\nning\" holds the control character '\\n'",
        ]
    );
    script = parse("test.ron", B1).unwrap();
    script.name = "B 1".into();
    assert_eq!(
        problems_of(&script),
        ["test.ron: node B 1: name: \"B 1\" holds a space: traces name the node by it"]
    );
}

/// A script built in code skips validation: a clamp with no range must not panic the node, as
/// f64::clamp would; the message is skipped instead.
#[test]
fn an_unvalidated_bad_clamp_skips_the_message_instead_of_panicking() {
    for (lo, hi) in [(5.0, 1.0), (f64::NAN, 1.0), (0.0, f64::NAN)] {
        let (sent, n) = run_unchecked(b1_with(Expr::Clamp(rpm(), lo, hi)), 2000.0);
        assert!(sent.is_empty(), "Clamp({lo}, {hi}) sent {sent:?}");
        // Power on 500 ms, boot 10, phase 5, period 100: 515 to 915 ms, five sends.
        assert_eq!(n.counts(), (0, 5), "Clamp({lo}, {hi})");
    }
    let (sent, n) = run_unchecked(b1_with(Expr::Scaled(rpm(), f64::NAN, 0.0)), 2000.0);
    assert!(sent.is_empty());
    assert_eq!(n.counts(), (0, 5));
}

/// Any f64: NaN, infinities, subnormals, the extremes, and ordinary values.
fn number() -> impl Strategy<Value = f64> {
    prop_oneof![
        prop::num::f64::ANY,
        -1e4..1e4f64,
        Just(0.0),
        Just(f64::MAX),
        Just(f64::MIN_POSITIVE / 2.0),
    ]
}

proptest! {
    /// Every number a field expression holds either fails validation, naming the field, or
    /// makes a node that sends every period with the value in the field's range; unvalidated,
    /// the node never panics and never sends a value the catalogue refuses.
    #[test]
    fn any_number_is_refused_or_sent_in_range(
        c in number(), gain in number(), offset in number(), lo in number(), hi in number(),
        step in number(), signal in -1e6..1e6f64, shape in 0..4usize,
    ) {
        let e = match shape {
            0 => Expr::Const(c),
            1 => Expr::Scaled(rpm(), gain, offset),
            2 => Expr::Clamp(Box::new(Expr::Scaled(rpm(), gain, offset)), lo, hi),
            _ => Expr::Quantize(Box::new(Expr::Clamp(Box::new(Expr::Scaled(rpm(), gain, offset)), lo, hi)), step),
        };
        let script = b1_with(e);
        let problems = problems_of(&script);
        let (sent, n) = run_unchecked(script, signal);
        for f in &sent {
            let d = catalogue::decode(f).unwrap().unwrap();
            for v in &d.values {
                prop_assert!(v.physical.is_finite() && v.in_range(), "{v:?}");
            }
        }
        if problems.is_empty() {
            prop_assert_eq!(n.counts(), (5, 0));
        } else {
            for p in &problems {
                prop_assert!(p.starts_with(FIELD), "{}", p);
            }
        }
    }
}

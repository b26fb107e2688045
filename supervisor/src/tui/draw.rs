//! Rendering a [`View`] with ratatui widgets.
//!
//! Contract: [`draw`] is pure (the frame's buffer is its only output) and fits any area: a
//! title line, the cab monitor panel on the left, the bus panel on the right; what does not fit
//! is cut, at any size down to nothing.

use super::view::{BusView, Clock, IdView, MonitorView, NodeView, Reading, View};
use bus::fault::ErrorState;
use ratatui::Frame;
use ratatui::layout::{Constraint, Layout, Rect};
use ratatui::style::{Color, Modifier, Style, Stylize};
use ratatui::text::{Line, Span};
use ratatui::widgets::{Block, Cell, Paragraph, Row, Table};

/// Width of the monitor panel when the terminal is wide enough.
const MONITOR_WIDTH: u16 = 58;
/// Narrowest the bus panel gets while the monitor panel is wider than that.
const BUS_MIN_WIDTH: u16 = 40;
/// Most lines the alarm list takes from the monitor panel.
const ALARM_LINES: u16 = 6;

/// Draws the whole screen into `frame`.
pub fn draw(frame: &mut Frame, view: &View) {
    let [title, body] = Layout::vertical([Constraint::Length(1), Constraint::Fill(1)]).areas(frame.area());
    frame.render_widget(Paragraph::new(title_line(view)), title);
    let [left, right] =
        Layout::horizontal([Constraint::Max(MONITOR_WIDTH), Constraint::Min(BUS_MIN_WIDTH)]).areas(body);
    monitor(frame, left, &view.monitor);
    bus(frame, right, &view.bus);
}

fn title_line(view: &View) -> Line<'static> {
    let clock = match view.clock {
        Clock::Virtual => "virtual time",
        Clock::RealTime => "real time",
    };
    let state = if view.finished {
        "finished".bold()
    } else {
        "running".into()
    };
    Line::from(vec![
        format!("harvemu {} ", view.machine).bold(),
        format!(" t {:.1} s ({clock}) ", view.now.as_secs_f64()).into(),
        state,
        "   q quits".dim(),
    ])
}

fn monitor(frame: &mut Frame, area: Rect, m: &MonitorView) {
    let mut title = format!(" Cab monitor F5: {}", m.phase);
    if let Some(mode) = &m.drive_mode {
        title.push_str(&format!(", {mode}"));
    }
    if m.frames_lost > 0 {
        title.push_str(&format!(", {} frames lost", m.frames_lost));
    }
    title.push(' ');
    let block = Block::bordered().title(title);
    let inner = block.inner(area);
    frame.render_widget(block, area);
    let alarm_lines = (m.alarms.len() as u16).clamp(1, ALARM_LINES);
    let [alarms, table] =
        Layout::vertical([Constraint::Length(alarm_lines), Constraint::Fill(1)]).areas(inner);
    frame.render_widget(Paragraph::new(alarm_lines_of(m, alarm_lines)), alarms);

    let right = |t: &'static str| Cell::from(Line::from(t).right_aligned());
    let header = Row::new([Cell::from(""), right("monitor"), right("plant")]).bold();
    let blank = Row::new([""; 5]);
    let rows: Vec<Row> = m
        .yields
        .iter()
        .map(reading_row)
        .chain(std::iter::once(blank))
        .chain(m.machine.iter().map(reading_row))
        .collect();
    let widths = [
        Constraint::Length(14),
        Constraint::Length(9),
        Constraint::Length(9),
        Constraint::Length(6),
        Constraint::Fill(1),
    ];
    frame.render_widget(Table::new(rows, widths).header(header), table);
}

fn alarm_lines_of(m: &MonitorView, lines: u16) -> Vec<Line<'static>> {
    if m.alarms.is_empty() {
        let text = if m.present {
            "no active alarm"
        } else {
            "no monitor: plant values only"
        };
        return vec![Line::from(text.dim())];
    }
    let red = Style::new().fg(Color::Red).add_modifier(Modifier::BOLD);
    let mut out: Vec<Line> = m
        .alarms
        .iter()
        .map(|a| {
            Line::from(format!(
                "ALARM {} {} since {:.1} s",
                a.node,
                a.name,
                a.raised.as_secs_f64()
            ))
            .style(red)
        })
        .collect();
    let lines = usize::from(lines);
    if out.len() > lines {
        // Say how many are hidden rather than cut the list silently.
        out.truncate(lines.saturating_sub(1));
        out.push(Line::from(format!("... {} more alarms", m.alarms.len() - out.len())).style(red));
    }
    out
}

fn number(v: Option<f64>, decimals: usize) -> Cell<'static> {
    let text = match v {
        Some(v) if v.is_finite() => format!("{v:.decimals$}"),
        Some(_) => "?".into(),
        None => "-".into(),
    };
    Cell::from(Line::from(text).right_aligned())
}

fn reading_row(r: &Reading) -> Row<'static> {
    Row::new([
        Cell::from(r.label.clone()),
        number(r.shown, r.decimals),
        number(r.truth, r.decimals),
        Cell::from(r.unit),
        Cell::from(r.note.clone()),
    ])
}

fn bus(frame: &mut Frame, area: Rect, b: &BusView) {
    let block = Block::bordered().title(" Bus ");
    let inner = block.inner(area);
    frame.render_widget(block, area);
    let load = Line::from(format!(
        "load {:.1} % (last 1 s {:.1} %)",
        b.load * 100.0,
        b.load_1s * 100.0
    ));
    let counts = Line::from(format!(
        "frames {}  error frames {}  overruns {}",
        b.frames, b.error_frames, b.overruns
    ));
    let cells: Vec<(String, Style)> = b.nodes.iter().map(node_cell).collect();
    let cell_width = cells.iter().map(|(t, _)| t.chars().count()).max().unwrap_or(0) + 2;
    let per_line = (usize::from(inner.width) / cell_width.max(1)).max(1);
    let mut lines = vec![load, counts];
    for chunk in cells.chunks(per_line) {
        lines.push(Line::from(
            chunk
                .iter()
                .map(|(t, style)| Span::styled(format!("{t:<cell_width$}"), *style))
                .collect::<Vec<_>>(),
        ));
    }
    lines.extend(b.events.iter().map(|e| Line::from(e.clone()).yellow()));
    // Nodes and events take at most half the panel: the identifiers need room too.
    let head = (lines.len() as u16).min((inner.height / 2).max(2));
    let [top, table] = Layout::vertical([Constraint::Length(head), Constraint::Fill(1)]).areas(inner);
    frame.render_widget(Paragraph::new(lines), top);

    let header = Row::new(["id", "message", "route", "fr/s", "last payload", "decoded"]).bold();
    let widths = [
        Constraint::Length(8),
        Constraint::Length(21),
        Constraint::Length(6),
        Constraint::Length(6),
        Constraint::Length(23),
        Constraint::Fill(1),
    ];
    let rows: Vec<Row> = b.ids.iter().map(id_row).collect();
    frame.render_widget(Table::new(rows, widths).header(header), table);
}

fn node_cell(n: &NodeView) -> (String, Style) {
    let (state, style) = match n.state {
        ErrorState::Active => ("active", Style::new()),
        ErrorState::Passive => ("passive", Style::new().fg(Color::Yellow).bold()),
        ErrorState::BusOff => ("bus-off", Style::new().fg(Color::Red).bold()),
    };
    let mut text = format!("{} {state} {}/{}", n.name, n.tec, n.rec);
    let mut style = style;
    if n.crashed {
        text.push_str(" crashed");
        style = Style::new().fg(Color::Red).bold();
    }
    if n.hung {
        text.push_str(" hung");
        style = Style::new().fg(Color::Red).bold();
    }
    (text, style)
}

fn id_row(v: &IdView) -> Row<'static> {
    let id = if v.extended {
        format!("{:08X}", v.id)
    } else {
        format!("{:03X}", v.id)
    };
    let route = v.route.map_or(String::new(), |(src, dst)| format!("{src}>{dst}"));
    let payload = if v.remote {
        "remote".to_string()
    } else {
        v.payload
            .iter()
            .map(|b| format!("{b:02X}"))
            .collect::<Vec<_>>()
            .join(" ")
    };
    let decoded = match &v.problem {
        Some(p) => Line::from(p.clone()).red(),
        None => Line::from(
            v.fields
                .iter()
                .map(|f| format!("{}={}", f.name, f.text))
                .collect::<Vec<_>>()
                .join(" "),
        ),
    };
    Row::new([
        Cell::from(id),
        Cell::from(v.message.unwrap_or("")),
        Cell::from(route),
        Cell::from(Line::from(format!("{:.1}", v.rate)).right_aligned()),
        Cell::from(payload),
        Cell::from(decoded),
    ])
}

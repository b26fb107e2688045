//! Rendering a [`View`] with ratatui widgets.
//!
//! Contract: [`draw`] is pure (the frame's buffer is its only output) and fits any area: a
//! title line, the cab monitor panel on the left, the bus panel on the right (below it when the
//! terminal is too narrow for both side by side); what does not fit is cut, at any size down to
//! nothing, but never a number: labels are cut, numbers are shown whole or as `#`s, and parts of
//! a line holding numbers are left out whole ([`super::fit`]).

use super::fit;
use super::view::{BusView, Clock, IdView, MonitorView, NodeView, Reading, View};
use bus::fault::ErrorState;
use ratatui::Frame;
use ratatui::layout::{Constraint, Layout, Rect};
use ratatui::style::{Color, Modifier, Style, Stylize};
use ratatui::text::{Line, Span};
use ratatui::widgets::{Block, Cell, Paragraph, Row, Table};

/// Narrowest the bus panel gets beside the monitor panel; when the terminal cannot give both
/// panels their width, the bus panel goes below the monitor's.
const BUS_MIN_WIDTH: u16 = 40;
/// Columns of the identifier table that are always there: the identifier and its rate.
const ID_WIDTH: usize = 8;
const RATE_WIDTH: usize = 6;
/// Widest the identifier table's message names, routes and payloads get.
const MESSAGE_WIDTH: usize = 21;
const ROUTE_WIDTH: usize = 6;
const PAYLOAD_WIDTH: usize = 23;
/// Room kept for the decoded fields before the route and the payload get theirs: a field such as
/// `setpoint=8.00 km/h` and then some.
const DECODED_MIN: usize = 24;
/// Most lines the alarm list takes from the monitor panel.
const ALARM_LINES: u16 = 6;

/// Draws the whole screen into `frame`.
pub fn draw(frame: &mut Frame, view: &View) {
    let [title, body] = Layout::vertical([Constraint::Length(1), Constraint::Fill(1)]).areas(frame.area());
    frame.render_widget(Paragraph::new(title_line(view, usize::from(title.width))), title);
    let columns = MonitorColumns::of(&view.monitor);
    let needed = columns.panel_width();
    let [left, right] = if body.width >= needed.saturating_add(BUS_MIN_WIDTH) {
        Layout::horizontal([Constraint::Length(needed), Constraint::Fill(1)]).areas(body)
    } else {
        // Too narrow for both side by side: the monitor on top, with the numbers whole.
        let height = columns
            .panel_height(&view.monitor)
            .min(body.height.saturating_mul(2) / 3);
        Layout::vertical([Constraint::Length(height), Constraint::Fill(1)]).areas(body)
    };
    monitor(frame, left, &view.monitor, &columns);
    bus(frame, right, &view.bus);
}

fn title_line(view: &View, width: usize) -> Line<'static> {
    let clock = match view.clock {
        Clock::Virtual => "(virtual time)",
        Clock::RealTime => "(real time)",
    };
    let state = if view.finished {
        "finished".bold()
    } else {
        "running".into()
    };
    let spans: Vec<Span<'static>> = vec![
        format!("harvemu {} ", view.machine).bold(),
        format!(" t {:.1} s", view.now.as_secs_f64()).into(),
        format!(" {clock} ").into(),
        state,
        "   q quits".dim(),
    ];
    // Whole spans only: the time is never cut.
    let mut used = 0;
    spans
        .into_iter()
        .take_while(|s| {
            used += s.content.chars().count();
            used <= width
        })
        .collect::<Vec<_>>()
        .into()
}

/// The widths the monitor's table needs to show everything whole.
struct MonitorColumns {
    label: usize,
    number: usize,
    unit: usize,
    note: usize,
}

impl MonitorColumns {
    fn of(m: &MonitorView) -> MonitorColumns {
        let readings = || m.yields.iter().chain(&m.machine);
        let widest = |f: &dyn Fn(&Reading) -> usize| readings().map(f).max().unwrap_or(0);
        MonitorColumns {
            label: widest(&|r| r.label.chars().count()),
            number: widest(&|r| {
                number_text(r.shown, r.decimals)
                    .len()
                    .max(number_text(r.truth, r.decimals).len())
            })
            .max("monitor".len()),
            unit: widest(&|r| r.unit.chars().count()),
            note: widest(&|r| r.note.chars().count()),
        }
    }

    /// The panel's width: borders, the columns and a space between each two.
    fn panel_width(&self) -> u16 {
        let inner = self.label + 1 + self.number + 1 + self.number + 1 + self.unit + 1 + self.note;
        u16::try_from(inner + 2).unwrap_or(u16::MAX)
    }

    /// The panel's height: borders, alarms, header, readings and the blank line between them.
    fn panel_height(&self, m: &MonitorView) -> u16 {
        let rows = m.yields.len() + 1 + m.machine.len();
        let alarms = usize::from(alarm_height(m));
        u16::try_from(2 + alarms + 1 + rows).unwrap_or(u16::MAX)
    }

    /// The columns of a table `width` wide: the numbers first, then the unit, the label and the
    /// note, each with what is left (a column that gets nothing is not shown).
    fn within(&self, width: usize) -> [usize; 5] {
        let mut rest = width;
        let mut take = |want: usize, first: bool| {
            let gap = usize::from(!first);
            let got = want.min(rest.saturating_sub(gap));
            if got > 0 {
                rest -= got + gap;
            }
            got
        };
        let monitor = take(self.number, true);
        let plant = take(self.number, false);
        let unit = take(self.unit, false);
        let label = take(self.label, false);
        let note = take(self.note, false);
        [label, monitor, plant, unit, note]
    }
}

fn alarm_height(m: &MonitorView) -> u16 {
    (m.alarms.len() as u16).clamp(1, ALARM_LINES)
}

fn monitor(frame: &mut Frame, area: Rect, m: &MonitorView, columns: &MonitorColumns) {
    let mut title = vec![format!(" Cab monitor F5: {}", m.phase)];
    if let Some(mode) = &m.drive_mode {
        title.push(mode.clone());
    }
    if m.frames_lost > 0 {
        title.push(format!("{} frames lost", m.frames_lost));
    }
    let title = fit::parts(&title, ", ", usize::from(area.width.saturating_sub(3))) + " ";
    let block = Block::bordered().title(title);
    let inner = block.inner(area);
    frame.render_widget(block, area);
    let alarm_lines = alarm_height(m);
    let [alarms, table] =
        Layout::vertical([Constraint::Length(alarm_lines), Constraint::Fill(1)]).areas(inner);
    frame.render_widget(Paragraph::new(alarm_lines_of(m, alarm_lines)), alarms);

    let widths = columns.within(usize::from(table.width));
    let header = row_text(widths, ["", "monitor", "plant", "", ""], true);
    let mut lines = vec![Line::from(header).bold()];
    lines.extend(m.yields.iter().map(|r| Line::from(reading_row(r, widths))));
    lines.push(Line::from(""));
    lines.extend(m.machine.iter().map(|r| Line::from(reading_row(r, widths))));
    frame.render_widget(Paragraph::new(lines), table);
}

/// One line of the monitor's table: label, monitor, plant, unit, note in `widths`.
fn row_text(widths: [usize; 5], cells: [&str; 5], header: bool) -> String {
    let mut out: Vec<String> = Vec::new();
    for (i, (w, text)) in widths.iter().zip(cells).enumerate() {
        if *w == 0 {
            continue;
        }
        out.push(match i {
            // Headers of the number columns are labels, right-aligned and cut if need be.
            1 | 2 if header => format!("{:>w$}", fit::label(text, *w).trim_end(), w = *w),
            1 | 2 => fit::number(text, *w),
            4 => {
                let words: Vec<String> = text.split(' ').map(str::to_owned).collect();
                fit::label(&fit::parts(&words, " ", *w), *w)
            }
            _ => fit::label(text, *w),
        });
    }
    out.join(" ")
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

fn number_text(v: Option<f64>, decimals: usize) -> String {
    match v {
        Some(v) if v.is_finite() => format!("{v:.decimals$}"),
        Some(_) => "?".into(),
        None => "-".into(),
    }
}

fn reading_row(r: &Reading, widths: [usize; 5]) -> String {
    let shown = number_text(r.shown, r.decimals);
    let truth = number_text(r.truth, r.decimals);
    row_text(widths, [&r.label, &shown, &truth, r.unit, &r.note], false)
}

/// As many of `parts` as fit `width` whole, with ` …` when some are left out (`…` alone when
/// not even the first fits): a cell never looks complete when it is not.
fn more(parts: &[String], width: usize) -> String {
    let all = fit::parts(parts, " ", width);
    if all.chars().count() == parts.join(" ").chars().count() {
        return all;
    }
    let some = fit::parts(parts, " ", width.saturating_sub(2));
    if some.is_empty() {
        "…".chars().take(width).collect()
    } else {
        format!("{some} …")
    }
}

/// Words of `text` that fit `width` whole.
fn words(text: &str, width: usize) -> String {
    let words: Vec<String> = text.split(' ').map(str::to_owned).collect();
    fit::parts(&words, " ", width)
}

fn bus(frame: &mut Frame, area: Rect, b: &BusView) {
    let block = Block::bordered().title(" Bus ");
    let inner = block.inner(area);
    frame.render_widget(block, area);
    let width = usize::from(inner.width);
    let load = [
        format!("load {:.1} %", b.load * 100.0),
        format!("(last 1 s {:.1} %)", b.load_1s * 100.0),
    ];
    let counts = [
        format!("frames {}", b.frames),
        format!("error frames {}", b.error_frames),
        format!("overruns {}", b.overruns),
    ];
    // One line when it fits whole, else two.
    let both = load.join(" ") + "  " + &counts.join("  ");
    let mut lines = if both.chars().count() <= width {
        vec![Line::from(both)]
    } else {
        vec![
            Line::from(fit::parts(&load, " ", width)),
            Line::from(fit::parts(&counts, "  ", width)),
        ]
    };
    // Nodes and events take at most half the panel: the identifiers need room too. Each node
    // with its state and counters when they all fit there, else in the compact form.
    let head_budget = usize::from((inner.height / 2).max(2));
    let node_rows = head_budget.saturating_sub(lines.len()).max(1);
    let full: Vec<(String, Style)> = b.nodes.iter().map(node_cell).collect();
    let rows_of = |cells: &[(String, Style)]| {
        let cell_width = cells.iter().map(|(t, _)| t.chars().count()).max().unwrap_or(0) + 2;
        let per_line = (width / cell_width.max(1)).max(1);
        (cell_width, per_line, cells.len().div_ceil(per_line))
    };
    let cells = if rows_of(&full).2 <= node_rows {
        full
    } else {
        b.nodes.iter().map(compact_cell).collect()
    };
    let (cell_width, per_line, _) = rows_of(&cells);
    for chunk in cells.chunks(per_line) {
        lines.push(Line::from(
            chunk
                .iter()
                .map(|(t, style)| Span::styled(format!("{:<cell_width$}", words(t, width)), *style))
                .collect::<Vec<_>>(),
        ));
    }
    lines.extend(b.events.iter().map(|e| Line::from(words(e, width)).yellow()));
    let head = (lines.len() as u16).min(head_budget as u16);
    let [top, table] = Layout::vertical([Constraint::Length(head), Constraint::Fill(1)]).areas(inner);
    frame.render_widget(Paragraph::new(lines), top);

    let columns = IdColumns::within(usize::from(table.width));
    let header = Row::new(columns.header()).bold();
    let rows: Vec<Row> = b.ids.iter().map(|v| id_row(v, &columns)).collect();
    frame.render_widget(Table::new(rows, columns.constraints()).header(header), table);
}

/// The identifier table's columns for a width: the identifier and its rate always, then the
/// message's name (cut if need be), the route, the payload and the decoded fields with what is
/// left. A column with no room is left out.
struct IdColumns {
    message: usize,
    route: usize,
    payload: usize,
    decoded: usize,
}

impl IdColumns {
    fn within(width: usize) -> IdColumns {
        let mut rest = width.saturating_sub(ID_WIDTH + 1 + RATE_WIDTH);
        let mut take = |want: usize| {
            let got = want.min(rest.saturating_sub(1));
            if got > 0 {
                rest -= got + 1;
            }
            got
        };
        let message = take(MESSAGE_WIDTH);
        // The decoded fields say most: their room is kept first, and what is left over at the
        // end is theirs too.
        let kept = take(DECODED_MIN);
        let route = take(ROUTE_WIDTH);
        let payload = take(PAYLOAD_WIDTH);
        let decoded = if kept > 0 { kept + rest } else { 0 };
        IdColumns {
            message,
            route,
            payload,
            decoded,
        }
    }

    /// (width, header) of each column shown, in order.
    fn shown(&self) -> Vec<(usize, &'static str)> {
        [
            (ID_WIDTH, "id"),
            (self.message, "message"),
            (self.route, "route"),
            (RATE_WIDTH, "fr/s"),
            (self.payload, "last payload"),
            (self.decoded, "decoded"),
        ]
        .into_iter()
        .filter(|(w, _)| *w > 0)
        .collect()
    }

    fn header(&self) -> Vec<String> {
        self.shown().iter().map(|(w, h)| fit::label(h, *w)).collect()
    }

    fn constraints(&self) -> Vec<Constraint> {
        self.shown()
            .iter()
            .map(|(w, _)| Constraint::Length(u16::try_from(*w).unwrap_or(u16::MAX)))
            .collect()
    }
}

/// A node in few columns: its name alone while it is error active and well, else with a mark
/// (`:P` passive, `:OFF` bus off, `:crash`, `:hung`), coloured as in the full form.
fn compact_cell(n: &NodeView) -> (String, Style) {
    let (mark, style) = if n.crashed {
        (":crash", Style::new().fg(Color::Red).bold())
    } else if n.hung {
        (":hung", Style::new().fg(Color::Red).bold())
    } else {
        match n.state {
            ErrorState::Active => ("", Style::new()),
            ErrorState::Passive => (":P", Style::new().fg(Color::Yellow).bold()),
            ErrorState::BusOff => (":OFF", Style::new().fg(Color::Red).bold()),
        }
    };
    (format!("{}{mark}", n.name), style)
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

fn id_row(v: &IdView, columns: &IdColumns) -> Row<'static> {
    let id = if v.extended {
        format!("{:08X}", v.id)
    } else {
        format!("{:03X}", v.id)
    };
    let route = v.route.clone().unwrap_or_default();
    let payload = if v.remote {
        "remote".to_string()
    } else {
        let bytes: Vec<String> = v.payload.iter().map(|b| format!("{b:02X}")).collect();
        // Whole bytes only, with a mark when some are left out.
        let shown = fit::parts(&bytes, " ", columns.payload);
        if shown.len() < bytes.join(" ").len() {
            let fewer = fit::parts(&bytes, " ", columns.payload.saturating_sub(2));
            format!("{fewer} …")
        } else {
            shown
        }
    };
    let decoded = match &v.problem {
        Some(p) => Line::from(more(
            &p.split(' ').map(str::to_owned).collect::<Vec<_>>(),
            columns.decoded,
        ))
        .red(),
        None => Line::from(more(
            &v.fields
                .iter()
                .map(|f| format!("{}={}", f.name, f.text))
                .collect::<Vec<_>>(),
            columns.decoded,
        )),
    };
    let mut cells = vec![Cell::from(fit::number(&id, ID_WIDTH))];
    if columns.message > 0 {
        cells.push(Cell::from(fit::label(
            v.message.as_deref().unwrap_or(""),
            columns.message,
        )));
    }
    if columns.route > 0 {
        cells.push(Cell::from(words(&route, columns.route)));
    }
    cells.push(Cell::from(fit::number(&format!("{:.1}", v.rate), RATE_WIDTH)));
    if columns.payload > 0 {
        cells.push(Cell::from(payload));
    }
    if columns.decoded > 0 {
        cells.push(Cell::from(decoded));
    }
    Row::new(cells)
}

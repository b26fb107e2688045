//! `--trace-cpu`: the instructions a firmware node executes within a window of bus time.

use super::FirmwareNode;
use bus::time::BusTime;

/// An instruction trace of one node over a window of bus time: each instruction that starts in
/// `[from, to]` is a line given to `sink` (see [`FirmwareNode::trace_cpu`]).
pub struct CpuTrace {
    /// First instant traced.
    pub from: BusTime,
    /// Last instant traced.
    pub to: BusTime,
    /// Takes each line, without its line break.
    pub sink: Box<dyn FnMut(&str)>,
}

impl FirmwareNode {
    /// Traces the instructions it executes from now on within `trace`'s window: bus time, cycle
    /// count, address, bytes, the instruction and its machine cycles, one line each, and
    /// interrupt entries. Only the path the node takes is traced, once. The trace moves on as
    /// the node's wakes do: while the window is open the node is woken even in a loop that
    /// changes nothing, and [`NodeLogic::run_ends`](bus::node::NodeLogic::run_ends) brings it to
    /// the end of the run (the last instruction that starts before it).
    pub fn trace_cpu(&mut self, trace: CpuTrace) {
        self.trace = Some(trace);
    }

    /// Whether a trace is on and its window not yet behind `now`: the node then asks to be
    /// woken even while it idles in a loop that changes nothing.
    pub(super) fn trace_open(&self) -> bool {
        self.failed.is_none()
            && self
                .trace
                .as_ref()
                .is_some_and(|t| self.now.clocks() <= self.clock_at(t.to))
    }

    /// The last clock before `n` to trace instruction by instruction, when the trace window
    /// meets the stretch from `now` to `n`.
    pub(super) fn traced_until(&self, n: u64) -> Option<u64> {
        let t = self.trace.as_ref()?;
        let start = self.now.clocks();
        let (from, to) = (self.clock_at(t.from), self.clock_at(t.to));
        (start < n && start <= to && n > from).then(|| n.min(to.saturating_add(1)))
    }

    /// Steps `now` to clock `last`, tracing the instructions in the window: the same path as
    /// [`FirmwareNode::project`] takes, one instruction at a time.
    pub(super) fn step_traced(&mut self, last: u64) {
        let Some(mut trace) = self.trace.take() else {
            return;
        };
        let code = &self.spec.image.code;
        let mut m = self.now.clone();
        let mut actions = Vec::new();
        while m.clocks() < last && !m.plant_stop {
            if m.cpu.inputs_due() {
                m.plant_stop = true;
                break;
            }
            let (pc, start, clock) = (m.cpu.pc(), m.cpu.cycles(), m.clocks());
            let step = match &self.counts {
                Some(c) => m.step(&mut *c.borrow_mut()),
                None => m.step(&mut ()),
            };
            let step = match step {
                Ok(step) => step,
                Err(e) => {
                    self.failed = Some(format!("{}: {e}", self.spec.name));
                    break;
                }
            };
            actions.extend(m.take_actions());
            let at = self.time_of(clock);
            if at < trace.from || at > trace.to {
                continue;
            }
            let line = match step.interrupt {
                Some(vector) => format!(
                    "{at} {start:>10} {pc:04X}  -> interrupt, vector {vector:04X}H ({} cycles)",
                    step.cycles
                ),
                None => {
                    let (text, len) = mcs51::disasm(code, pc);
                    let bytes: Vec<String> = (0..len)
                        .map(|i| {
                            format!(
                                "{:02X}",
                                code.get(usize::from(pc.wrapping_add(i))).copied().unwrap_or(0xFF)
                            )
                        })
                        .collect();
                    format!(
                        "{at} {start:>10} {pc:04X}  {:<9} {text:<22} {} cycle(s)",
                        bytes.join(" "),
                        step.cycles
                    )
                }
            };
            (trace.sink)(&line);
        }
        self.trace = Some(trace);
        self.command(actions);
        self.now = m;
        self.serial();
        self.log_writes();
        // What ran ahead of the old `now` is not the path from here.
        self.run_ahead();
    }
}

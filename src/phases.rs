//! The console phase report, after the thesis's console log (§5.3.6, Fig. 5.44–5.46): each phase
//! of a render with its own duration and the time elapsed since the start when it finished
//! (the thesis printed the latter: "Primeros choques: 1735.66", "hecho en: 2441.64", in ms), plus the
//! acceleration structure that was built, which is what the thesis's three figures compare.

use std::time::Duration;

#[derive(Clone, Debug, Default)]
pub struct PhaseReport {
    phases: Vec<(String, Duration)>,
    notes: Vec<String>,
}

impl PhaseReport {
    pub fn new() -> PhaseReport {
        PhaseReport::default()
    }

    /// Appends a phase that took `d`, in order.
    pub fn phase(&mut self, name: impl Into<String>, d: Duration) {
        self.phases.push((name.into(), d));
    }

    /// Appends a line printed after the phases (ray counts, structure sizes).
    pub fn note(&mut self, line: impl Into<String>) {
        self.notes.push(line.into());
    }

    pub fn total(&self) -> Duration {
        self.phases.iter().map(|(_, d)| *d).sum()
    }

    /// The report as lines: `phase   duration   (done at cumulative)`.
    pub fn lines(&self) -> Vec<String> {
        let width = self
            .phases
            .iter()
            .map(|(n, _)| n.chars().count())
            .max()
            .unwrap_or(0)
            .max(8);
        let mut at = Duration::ZERO;
        let mut out = Vec::with_capacity(self.phases.len() + self.notes.len() + 1);
        for (name, d) in &self.phases {
            at += *d;
            out.push(format!(
                "{name:<width$}  {:>12}   (done at {:>12})",
                fmt_ms(*d),
                fmt_ms(at)
            ));
        }
        out.push(format!("{:<width$}  {:>12}", "total", fmt_ms(at)));
        out.extend(self.notes.iter().cloned());
        out
    }
}

/// Milliseconds with three decimals, like the thesis's log.
pub fn fmt_ms(d: Duration) -> String {
    format!("{:.3} ms", d.as_secs_f64() * 1e3)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cumulative_times_add_up() {
        let mut r = PhaseReport::new();
        r.phase("load", Duration::from_millis(2));
        r.phase("acceleration structure", Duration::from_millis(3));
        r.phase("render", Duration::from_millis(10));
        r.note("rays 100");
        let l = r.lines();
        assert_eq!(l.len(), 5);
        assert!(l[1].contains("3.000 ms") && l[1].contains("done at") && l[1].contains("5.000 ms"));
        assert!(l[3].starts_with("total") && l[3].contains("15.000 ms"));
        assert_eq!(r.total(), Duration::from_millis(15));
    }
}

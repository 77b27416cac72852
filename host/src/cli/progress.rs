//! What the command line shows while it works: a spinner or bar per stage on a terminal
//! (nothing when stderr is not one, or with `--quiet`), and each stage's time at the end.

use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// The stages of one command, timed in order.
pub struct Stages {
    quiet: bool,
    done: Vec<(&'static str, Duration)>,
}

impl Stages {
    /// The stages of a command; `quiet` also silences every note of the run.
    pub fn new(quiet: bool) -> Self {
        Stages {
            quiet,
            done: Vec::new(),
        }
    }

    /// Runs stage `name` under a spinner and records its time (added up over repeated runs).
    pub fn run<T>(&mut self, name: &'static str, stage: impl FnOnce() -> T) -> T {
        self.run_counted(name, 0, |_| stage())
    }

    /// Runs stage `name`, which advances the bar it is given to `total` (a spinner when
    /// `total` is 0), and records its time.
    pub fn run_counted<T>(&mut self, name: &'static str, total: u64, stage: impl FnOnce(&ProgressBar) -> T) -> T {
        let bar = self.bar(name, total);
        let started = Instant::now();
        let result = stage(&bar);
        bar.finish_and_clear();
        // A stage run again (a turntable's frames) adds to its time.
        let elapsed = started.elapsed();
        match self.done.iter_mut().find(|(n, _)| *n == name) {
            Some((_, total)) => *total += elapsed,
            None => self.done.push((name, elapsed)),
        }
        result
    }

    /// A bar (or spinner) drawn on stderr when it is a terminal, never when quiet.
    pub fn bar(&self, message: &str, total: u64) -> ProgressBar {
        if self.quiet {
            return ProgressBar::hidden();
        }
        let (bar, template) = match total {
            0 => (ProgressBar::new_spinner(), "{spinner} {msg} {elapsed}"),
            n => (
                ProgressBar::new(n),
                "{msg} {bar:30} {percent:>3}% {elapsed} (eta {eta})",
            ),
        };
        bar.set_draw_target(ProgressDrawTarget::stderr());
        bar.set_style(ProgressStyle::with_template(template).expect("a valid template"));
        bar.set_message(message.to_string());
        bar.enable_steady_tick(Duration::from_millis(120));
        bar
    }

    /// Prints a line unless quiet.
    pub fn say(&self, line: impl AsRef<str>) {
        if !self.quiet {
            eprintln!("{}", line.as_ref());
        }
    }

    /// Every stage's time and the total, unless quiet: `load 0.31 s, build 5.30 s, ... (total 5.70 s)`.
    pub fn report(&self) {
        let stages: Vec<String> = self
            .done
            .iter()
            .map(|(name, t)| format!("{name} {:.2} s", t.as_secs_f64()))
            .collect();
        let total: Duration = self.done.iter().map(|(_, t)| *t).sum();
        self.say(format!("{} (total {:.2} s)", stages.join(", "), total.as_secs_f64()));
    }
}

/// The library's stages, notes and warnings as the command line shows them.
impl gridrt::progress::Progress for Stages {
    fn stage(&mut self, name: &'static str, work: &mut dyn FnMut()) {
        self.run(name, work)
    }

    fn counted_stage(&mut self, name: &'static str, total: u64, work: &mut dyn FnMut(gridrt::progress::Advance)) {
        self.run_counted(name, total, |bar| work(&|n| bar.inc(n)))
    }

    fn say(&mut self, line: &str) {
        Stages::say(self, line)
    }

    fn note(&mut self, line: &str) {
        Stages::say(self, format!("note: {line}"));
    }

    fn warning(&mut self, line: &str) {
        eprintln!("warning: {line}");
    }
}

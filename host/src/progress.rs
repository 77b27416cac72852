//! How long work tells its caller what it is doing: stages as they run, and notes and
//! warnings as they arise. The library prints nothing; a caller that shows progress (the
//! command line's bars and stage times) implements [`Progress`], one that does not passes
//! [`Silent`].

/// Told how many steps of a counted stage have finished since it was last told, from any
/// thread.
pub type Advance<'a> = &'a (dyn Fn(u64) + Sync);

/// What a long call reports while it works.
pub trait Progress {
    /// Runs `work`, the stage `name` of the call.
    fn stage(&mut self, name: &'static str, work: &mut dyn FnMut());

    /// Runs `work`, the stage `name` of the call, which does `total` steps and reports those
    /// it finishes to the [`Advance`] it is given.
    fn counted_stage(&mut self, name: &'static str, total: u64, work: &mut dyn FnMut(Advance)) {
        let _ = total;
        self.stage(name, &mut || work(&|_| ()))
    }

    /// A line of what was made or found (a scene's size, a file written).
    fn say(&mut self, line: &str) {
        let _ = line;
    }

    /// Something worth knowing that asks nothing of the user (one line).
    fn note(&mut self, line: &str) {
        let _ = line;
    }

    /// Something the user may need to act on (one line, naming the file).
    fn warning(&mut self, line: &str) {
        let _ = line;
    }
}

/// Reports nothing.
pub struct Silent;

impl Progress for Silent {
    fn stage(&mut self, _name: &'static str, work: &mut dyn FnMut()) {
        work()
    }
}

/// `work` as the counted stage `name` of `progress` (see [`Progress::counted_stage`]),
/// returning what it returns.
pub fn run_counted<T>(
    progress: &mut dyn Progress,
    name: &'static str,
    total: u64,
    work: impl FnOnce(Advance) -> T,
) -> T {
    let mut work = Some(work);
    let mut result = None;
    progress.counted_stage(name, total, &mut |advance| result = work.take().map(|w| w(advance)));
    result.expect("a stage runs its work")
}

/// `work` as stage `name` of `progress`, returning what it returns.
pub fn run<T>(progress: &mut dyn Progress, name: &'static str, work: impl FnOnce() -> T) -> T {
    let mut work = Some(work);
    let mut result = None;
    progress.stage(name, &mut || result = work.take().map(|w| w()));
    result.expect("a stage runs its work")
}

//! [`IntegrityWatcher`]: the configuration's integrity re-checked on its own thread, the
//! results sent to the supervisor loop as [`Command`]s.
//!
//! Reading and hashing the files takes milliseconds: never on the supervisor's thread, whose
//! lease is renewed every cycle. `motus safety run` and the station's juggler both start one.
//! Its period runs on a [`motus_clock::Clock`] ([`IntegrityWatcher::with_clock`]; the system
//! clock by default).

use motus_realtime::MailboxSender;
use std::io;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use motus_clock::{SharedClock, SystemClock};
use motus_safety::{ConfigFiles, RuleSet};

use crate::inputs::{InputError, InputMap};
use crate::runner::Command;

/// Builds the supervisor's inputs for new rules (the segment's value map for their nodes).
pub type InputsFor = Box<dyn Fn(&RuleSet) -> Result<InputMap, InputError> + Send>;

/// Longest sleep between two looks at the stop flag.
const STOP_POLL: Duration = Duration::from_millis(50);

/// Re-checks the approved configuration files ([`ConfigFiles::check`]) every period (see the
/// module documentation).
pub struct IntegrityWatcher {
    files: ConfigFiles,
    every: Duration,
    reload: Option<(RuleSet, InputsFor)>,
    clock: SharedClock,
}

impl std::fmt::Debug for IntegrityWatcher {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("IntegrityWatcher")
            .field("files", &self.files)
            .field("every", &self.every)
            .field("reload", &self.reload.is_some())
            .finish()
    }
}

impl IntegrityWatcher {
    /// A watcher of `files`, checking them every `every`.
    pub fn new(files: ConfigFiles, every: Duration) -> Self {
        Self { files, every, reload: None, clock: SystemClock::shared() }
    }

    /// Counts the period on `clock` (the supervisor's) instead of the system clock.
    #[must_use]
    pub fn with_clock(mut self, clock: SharedClock) -> Self {
        self.clock = clock;
        self
    }

    /// Also installs approved rules that differ from the `running` ones (a new approval of
    /// changed rules): [`Command::Rules`] with the inputs `inputs` builds for them, before
    /// the integrity result.
    #[must_use]
    pub fn reload_rules(mut self, running: RuleSet, inputs: InputsFor) -> Self {
        self.reload = Some((running, inputs));
        self
    }

    /// The files watched.
    pub fn files(&self) -> &ConfigFiles {
        &self.files
    }

    /// One check: the commands for the supervisor, in order ([`Command::Rules`] when the
    /// approved rules changed and [`IntegrityWatcher::reload_rules`] asked for it, then
    /// [`Command::Integrity`]).
    pub fn check(&mut self) -> Vec<Command> {
        let rules = match self.files.check() {
            Ok(rules) => rules,
            Err(e) => return vec![Command::Integrity(Err(e.to_string()))],
        };
        let mut out = Vec::new();
        if let Some((running, inputs_for)) = &mut self.reload {
            if rules.config() != running.config() {
                match inputs_for(&rules) {
                    Ok(inputs) => {
                        tracing::warn!(rules = %self.files.rules.display(), "approved rules changed: installing them");
                        out.push(Command::Rules { rules: Box::new(rules.clone()), inputs: Box::new(inputs) });
                        *running = rules;
                    }
                    Err(e) => {
                        let why = format!("the approved rules cannot be supervised on this segment: {e}");
                        return vec![Command::Integrity(Err(why))];
                    }
                }
            }
        }
        out.push(Command::Integrity(Ok(())));
        out
    }

    /// Starts the thread `name`: a check now, then one every period, until `stop` is set or
    /// the supervisor's channel closes. The thread takes part in the watcher's clock
    /// ([`motus_clock::spawn`]) and looks at `stop` at least every 50 ms of it.
    ///
    /// # Errors
    /// The thread cannot be spawned.
    pub fn spawn(
        mut self,
        name: &str,
        commands: MailboxSender<Command>,
        stop: Arc<AtomicBool>,
    ) -> io::Result<JoinHandle<()>> {
        let clock = Arc::clone(&self.clock);
        motus_clock::spawn(&clock, std::thread::Builder::new().name(name.into()), move || {
            let mut next = self.clock.now();
            while !stop.load(Ordering::Relaxed) {
                let now = self.clock.now();
                if now < next {
                    self.clock.sleep((next - now).min(STOP_POLL));
                    continue;
                }
                next = now + self.every;
                for c in self.check() {
                    if commands.send(c).is_err() {
                        return;
                    }
                }
            }
        })
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]
    use super::*;
    use motus_safety::config_files::{approve, read_key, read_snapshot};
    use motus_safety::{JUGGLER_DRIVES_TOML, JUGGLER_TOML};

    fn files(dir: &std::path::Path) -> ConfigFiles {
        let f = ConfigFiles {
            rules: dir.join("juggler.toml"),
            drives: Some(dir.join("drives.toml")),
            approval: dir.join("juggler.approved"),
            key: dir.join("admin.key"),
        };
        std::fs::write(&f.rules, JUGGLER_TOML).unwrap();
        std::fs::write(f.drives.as_ref().unwrap(), JUGGLER_DRIVES_TOML).unwrap();
        std::fs::write(&f.key, "an-administrator-key-0123456789").unwrap();
        f
    }

    fn approve_now(f: &ConfigFiles) {
        let (_, snap) = read_snapshot(&f.rules, f.drives.as_deref()).unwrap();
        approve(&snap, "alice", "test", &read_key(&f.key).unwrap(), &f.approval).unwrap();
    }

    fn inputs_for() -> InputsFor {
        Box::new(|r: &RuleSet| InputMap::new(r, crate::juggler::value_map(r), 0x10))
    }

    #[test]
    fn check_reports_integrity_and_reloads_newly_approved_rules_once() {
        let dir = tempfile::tempdir().unwrap();
        let f = files(dir.path());
        let running = RuleSet::from_toml(JUGGLER_TOML).unwrap();
        let mut w =
            IntegrityWatcher::new(f.clone(), Duration::from_secs(1)).reload_rules(running, inputs_for());
        // No approval yet.
        let c = w.check();
        assert!(matches!(&c[..], [Command::Integrity(Err(e))] if e.contains("juggler.approved")), "{c:?}");
        approve_now(&f);
        assert!(matches!(&w.check()[..], [Command::Integrity(Ok(()))]));
        // A changed rule without approval: refused, nothing installed.
        let edited = JUGGLER_TOML.replace("max_sample_age = 3 ", "max_sample_age = 2 ");
        assert_ne!(edited, JUGGLER_TOML);
        std::fs::write(&f.rules, &edited).unwrap();
        let c = w.check();
        assert!(matches!(&c[..], [Command::Integrity(Err(e))] if e.contains("max_sample_age")), "{c:?}");
        // Approved: installed once, then only the integrity.
        approve_now(&f);
        let c = w.check();
        assert!(
            matches!(&c[..], [Command::Rules { rules, .. }, Command::Integrity(Ok(()))]
                if rules.config().supervisor.max_sample_age == 2),
            "{c:?}"
        );
        assert!(matches!(&w.check()[..], [Command::Integrity(Ok(()))]));
        // A changed drive parameter names the drive and the field.
        let drives = f.drives.as_ref().unwrap();
        std::fs::write(drives, JUGGLER_DRIVES_TOML.replacen("homing_mode = 0", "homing_mode = 7", 1))
            .unwrap();
        let c = w.check();
        assert!(
            matches!(&c[..], [Command::Integrity(Err(e))] if e.contains("drive[arm_left].homing_mode: 0 -> 7")),
            "{c:?}"
        );
    }

    #[test]
    fn the_thread_checks_at_once_and_ends_with_the_stop_flag() {
        let dir = tempfile::tempdir().unwrap();
        let f = files(dir.path());
        approve_now(&f);
        let (tx, rx) = motus_realtime::mailbox();
        let stop = Arc::new(AtomicBool::new(false));
        let t = IntegrityWatcher::new(f, Duration::from_millis(10))
            .spawn("test-integrity", tx, Arc::clone(&stop))
            .unwrap();
        let end = std::time::Instant::now() + Duration::from_secs(30);
        let mut seen = Vec::new();
        while seen.len() < 3 && std::time::Instant::now() < end {
            seen.extend(rx.try_take());
            std::thread::sleep(Duration::from_millis(5));
        }
        assert!(seen.len() >= 3, "{seen:?}");
        for c in &seen {
            assert!(matches!(c, Command::Integrity(Ok(()))), "{c:?}");
        }
        stop.store(true, Ordering::Relaxed);
        t.join().unwrap();
    }
}

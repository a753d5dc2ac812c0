//! `motus safety check`: the supervisor over a recorded or generated trace.

use crate::cli::SafetyCommand;
use anyhow::{Context, Result};
use motus_safety::RuleSet;

/// Runs a `safety` command.
pub fn run(cmd: SafetyCommand) -> Result<()> {
    match cmd {
        SafetyCommand::Check { rules, trace } => {
            let text = std::fs::read_to_string(&rules)
                .with_context(|| format!("cannot read {}", rules.display()))?;
            let set = RuleSet::from_toml(&text)
                .with_context(|| format!("invalid rules file {}", rules.display()))?;
            let csv = std::fs::read_to_string(&trace)
                .with_context(|| format!("cannot read {}", trace.display()))?;
            let rows = motus_safety::trace::evaluate(&set, &csv)
                .with_context(|| format!("invalid trace {}", trace.display()))?;
            print!("{}", motus_safety::trace::format_rows(&set, &rows));
            Ok(())
        }
    }
}

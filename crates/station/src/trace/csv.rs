//! CSV export: `time_s,<name> (<unit>),...`, one row per timestamp, empty cells where a
//! signal has no sample at that time.

use std::io::Write;
use std::time::Duration;

use super::ring::Sample;
use super::SignalInfo;

/// Formats a time as seconds with nanosecond digits (exact, no float rounding).
pub(crate) fn seconds(t: Duration) -> String {
    format!("{}.{:09}", t.as_secs(), t.subsec_nanos())
}

/// Writes columns of samples (each oldest first) merged by timestamp.
pub(crate) fn write(cols: &[(&SignalInfo, Vec<Sample>)], out: &mut dyn Write) -> std::io::Result<()> {
    let mut header = String::from("time_s");
    for (info, _) in cols {
        header.push(',');
        header.push_str(&info.name);
        if !info.unit.is_empty() {
            header.push_str(&format!(" ({})", info.unit));
        }
    }
    writeln!(out, "{header}")?;
    let mut heads = vec![0usize; cols.len()];
    loop {
        let next = cols.iter().zip(&heads).filter_map(|((_, samples), &h)| samples.get(h).map(|s| s.t)).min();
        let Some(t) = next else { break };
        let mut row = seconds(t);
        for ((_, samples), h) in cols.iter().zip(heads.iter_mut()) {
            row.push(',');
            if let Some(s) = samples.get(*h).filter(|s| s.t == t) {
                row.push_str(&s.value.to_string());
                *h += 1;
            }
        }
        writeln!(out, "{row}")?;
    }
    Ok(())
}

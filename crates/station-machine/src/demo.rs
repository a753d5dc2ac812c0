//! The demo cell written into a directory, ready for [`crate::StationMachine::start_file`]:
//! the shipped `crates/station/examples/demo-cell.toml` with its links, ports and files moved
//! into that directory, so `motus demo` needs no root, no fixed paths and no free port 29536.

use std::io;
use std::path::{Path, PathBuf};

const DEMO_CELL: &str = include_str!("../../station/examples/demo-cell.toml");
const DRILL_PLATE: &str = include_str!("../../station/examples/programs/drill-plate.ngc");
const JUGGLE_CSV: &str = include_str!("../../station/examples/programs/juggle.csv");
const OMNI_SQUARE: &str = include_str!("../../station/examples/programs/omni-square.toml");

/// A free TCP port on 127.0.0.1 (probed now).
pub fn free_tcp_port() -> io::Result<u16> {
    Ok(std::net::TcpListener::bind("127.0.0.1:0")?.local_addr()?.port())
}

/// A name for a demo's in-process POWERLINK segment, unique in this process (tests start
/// several demo cells in one process).
fn unique_segment() -> String {
    static NEXT: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
    format!("{}-{}", std::process::id(), NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed))
}

/// Writes the demo cell into `dir` with the station listening on `listen`; returns the path
/// of the cell file. The juggler's segment runs inside the process (`mem://`) on a shared,
/// non-real-time host, so its rules get a 1 ms cycle (the simulated segment follows it), a 9 ms lease and data up to
/// 15 cycles old (the shipped rules are for the real machine's 400 us, 0.8 ms and 3 cycles);
/// the supervisor's prediction horizon grows with them, so the demo is more cautious, not
/// less.
pub fn write_demo_cell(dir: &Path, listen: &str) -> io::Result<PathBuf> {
    let programs = dir.join("programs");
    std::fs::create_dir_all(&programs)?;
    std::fs::create_dir_all(dir.join("links"))?;
    std::fs::write(programs.join("drill-plate.ngc"), DRILL_PLATE)?;
    std::fs::write(programs.join("juggle.csv"), JUGGLE_CSV)?;
    std::fs::write(programs.join("omni-square.toml"), OMNI_SQUARE)?;
    let rules = motus_safety::JUGGLER_TOML
        .replace("cycle_time = 0.0004", "cycle_time = 0.001")
        .replace("lease_time = 0.0008", "lease_time = 0.009")
        .replace("max_sample_age = 3 ", "max_sample_age = 15 ");
    std::fs::write(dir.join("juggler.toml"), &rules)?;
    // The juggler's drive parameters (the simulated amplifiers'; the timing changes above do
    // not touch them), approved with the rules.
    std::fs::write(dir.join("juggler-drives.toml"), motus_safety::JUGGLER_DRIVES_TOML)?;
    approve_demo_configuration(dir)?;
    let cell = DEMO_CELL
        .replace("/tmp/motus-demo/", &format!("{}/links/", dir.display()))
        .replace("127.0.0.1:29536", &format!("127.0.0.1:{}", free_tcp_port()?))
        // The juggler's whole segment runs inside the demo: an in-process medium (no socket,
        // no kernel path; see motus_epl::transport::MemLink), one per demo cell.
        .replace("udp://127.0.0.1:24000", &format!("mem://juggler-{}", unique_segment()))
        .replace("../../safety/examples/juggler.toml", "juggler.toml")
        .replace("../../safety/examples/juggler-drives.toml", "juggler-drives.toml")
        .replace("listen = \"127.0.0.1:8080\"", &format!("listen = \"{listen}\""));
    let path = dir.join("demo-cell.toml");
    std::fs::write(&path, cell)?;
    Ok(path)
}

/// The demo's administrator approves the juggler's rules and drive parameters: a random key
/// (mode 0600) and the signed approval in `dir/data`, written by the one approval signer
/// ([`motus_safety::config_files::approve`], as `motus safety approve`).
fn approve_demo_configuration(dir: &Path) -> io::Result<()> {
    use motus_safety::config_files;
    use std::os::unix::fs::PermissionsExt;
    let data = dir.join("data");
    std::fs::create_dir_all(&data)?;
    let key: String = {
        use rand::Rng;
        rand::thread_rng().sample_iter(&rand::distributions::Alphanumeric).take(40).map(char::from).collect()
    };
    let key_path = data.join("admin.key");
    std::fs::write(&key_path, &key)?;
    std::fs::set_permissions(&key_path, std::fs::Permissions::from_mode(0o600))?;
    let other = |e: config_files::FilesError| io::Error::other(e.to_string());
    let (_, snapshot) =
        config_files::read_snapshot(&dir.join("juggler.toml"), Some(&dir.join("juggler-drives.toml")))
            .map_err(other)?;
    config_files::approve(&snapshot, "demo-admin", "demo", key.as_bytes(), &data.join("juggler.approved"))
        .map_err(other)?;
    Ok(())
}

//! Validates a cell file and prints the errors (file:line:column: message) or a summary.
//!
//! `cargo run -p motus-station --example check_cell -- <cell.toml>`
#![allow(missing_docs)]

fn main() {
    let Some(path) = std::env::args().nth(1) else {
        eprintln!("usage: check_cell <cell.toml>");
        std::process::exit(2);
    };
    match motus_station::config::load(std::path::Path::new(&path)) {
        Ok(cell) => println!(
            "{}: {} links, {} devices, {} axes, {} groups, {} tasks in {} classes, {} programs",
            cell.station.name,
            cell.links.len(),
            cell.devices.len(),
            cell.axes.len(),
            cell.groups.len(),
            cell.tasks.len(),
            cell.task_classes().len(),
            cell.programs.len()
        ),
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(1);
        }
    }
}

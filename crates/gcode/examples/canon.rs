//! `cargo run --example canon -- prog.ngc [--rs274] [--linuxcnc]`: prints the canonical
//! calls, one per line (full precision, or `rs274`'s `%5d N..... ` layout with 4
//! decimals); `--linuxcnc` reads M60-M68 as LinuxCNC does ([`MCodeDialect::LinuxCnc`]).
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

use std::io::Write;

use motus_gcode::{format_canon, format_line, Interpreter, InterpreterConfig, MCodeDialect, Precision};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let path = args.get(1).expect("usage: canon <file.ngc> [--rs274]");
    let rs274 = args.iter().any(|a| a == "--rs274");
    let src = std::fs::read_to_string(path).unwrap();
    let out = std::io::stdout();
    let mut out = std::io::BufWriter::new(out.lock());
    let m_codes =
        if args.iter().any(|a| a == "--linuxcnc") { MCodeDialect::LinuxCnc } else { MCodeDialect::Seed };
    let config = InterpreterConfig { m_codes, ..InterpreterConfig::default() };
    for (k, call) in Interpreter::with_config(&src, config).enumerate() {
        match call {
            Ok(c) if rs274 => {
                let counter = u32::try_from(k + 1).unwrap_or(u32::MAX);
                writeln!(out, "{}", format_line(counter, &c, Precision::Rs274)).unwrap();
            }
            Ok(c) => writeln!(out, "{}", format_canon(&c.canon, Precision::Full)).unwrap(),
            Err(e) => {
                out.flush().unwrap();
                eprintln!("{}", e.with_file(path.as_str()));
                std::process::exit(1);
            }
        }
    }
}

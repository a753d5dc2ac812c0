//! The benchmark program shared by `benches/interpret.rs` and `examples/vs_rs274.rs`.

/// A deterministic program of `lines` lines: set-up, then G1 lines with a parameter
/// expression, G2 I/J arcs, G3 R arcs and lines assigning `#1` with functions of it
/// (cycling in that order), then `M2`. Both LinuxCNC's `rs274` and Motus run it to
/// the end (no error): about one canonical call per line.
pub fn program(lines: usize) -> String {
    let mut s = String::with_capacity(lines * 26);
    s.push_str("G21 G90 G17 F1000\n#1=0\n");
    let mut k = 0;
    while k + 3 < lines {
        match k % 4 {
            0 => s.push_str("G1 X0 Y0 Z[-[#1 MOD 5] * 0.01]\n"),
            1 => s.push_str("G2 X2 Y0 I1 J0\n"),
            2 => s.push_str("G3 X4 Y0 R1\n"),
            _ => s.push_str("#1=[#1 + 1.5] G1 X[4 + SIN[#1]] Y[COS[#1] * 2]\n"),
        }
        k += 1;
    }
    s.push_str("M2\n");
    s
}

//! The technology side of the M-function handshake.

use motus_cnc_planner::ExArray;
use motus_cnc_tech::drilling::DrillingInfo;
use motus_cnc_tech::machine::Hole;
use motus_cnc_tech::plc_interface::ExtType;
use motus_cnc_tech::{DrillingCell, MDisposition, Task};
use thiserror::Error;

/// The technology refused or failed.
#[derive(Debug, Error)]
#[error("technology: {0}")]
pub struct TechnologyError(pub String);

/// What the program runner needs from the technology (the PLC side).
pub trait Technology {
    /// The path reached M`number`; `Ok(true)`: the program must wait for its acknowledgement.
    fn m_function(&mut self, number: u16, sync: bool) -> Result<bool, TechnologyError>;
    /// The path reached an external parameter write.
    fn external(&mut self, array: ExArray, index: u8, value: f64) -> Result<(), TechnologyError>;
    /// One cycle with the program's X/Y; returns the M-functions acknowledged in it.
    fn cycle(&mut self, dt: f64, program_xy: [f64; 2]) -> Result<Vec<u16>, TechnologyError>;
}

/// No technology: every M-function is acknowledged at once (planning, dry runs).
#[derive(Debug, Default)]
pub struct NoTechnology {
    pending: Vec<u16>,
}

impl Technology for NoTechnology {
    fn m_function(&mut self, number: u16, sync: bool) -> Result<bool, TechnologyError> {
        if sync {
            self.pending.push(number);
        }
        Ok(sync)
    }
    fn external(&mut self, _: ExArray, _: u8, _: f64) -> Result<(), TechnologyError> {
        Ok(())
    }
    fn cycle(&mut self, _: f64, _: [f64; 2]) -> Result<Vec<u16>, TechnologyError> {
        Ok(std::mem::take(&mut self.pending))
    }
}

/// The drilling unit (M60-M64, EXW60/EXF61/EXF62) on the simulated machine.
pub struct DrillingTechnology {
    /// The cell (task, spindle, simulated machine).
    pub cell: DrillingCell,
}

impl DrillingTechnology {
    /// The drilling unit with default parameters on the default simulated machine.
    pub fn simulated() -> Self {
        Self { cell: DrillingCell::new(Default::default(), Default::default(), Default::default()) }
    }

    /// Holes drilled so far.
    pub fn holes(&self) -> &[Hole] {
        self.cell.machine().holes()
    }

    /// The drilling task's Info (state machine, flags).
    pub fn info(&self) -> &DrillingInfo {
        self.cell.drilling().info()
    }
}

impl Technology for DrillingTechnology {
    fn m_function(&mut self, number: u16, _sync: bool) -> Result<bool, TechnologyError> {
        match self.cell.on_m_function(number) {
            Ok(MDisposition::Wait) => Ok(true),
            Ok(MDisposition::Continue) => Ok(false),
            Err(e) => Err(TechnologyError(e.to_string())),
        }
    }

    fn external(&mut self, array: ExArray, index: u8, value: f64) -> Result<(), TechnologyError> {
        let ty = match array {
            ExArray::B => ExtType::B,
            ExArray::W => ExtType::W,
            ExArray::L => ExtType::L,
            ExArray::F => ExtType::F,
        };
        self.cell
            .set_external(ty, usize::from(index), value)
            .map(|_| ())
            .map_err(|e| TechnologyError(e.to_string()))
    }

    fn cycle(&mut self, dt: f64, program_xy: [f64; 2]) -> Result<Vec<u16>, TechnologyError> {
        let c = self.cell.cycle(dt, program_xy);
        if let Some(e) = c.error {
            return Err(TechnologyError(format!("{e:?}")));
        }
        Ok(c.acknowledged)
    }
}

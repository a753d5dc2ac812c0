//! Uploaded programs and the CNC program service.

use std::collections::BTreeMap;
use std::sync::Mutex;

use motus_cnc::{Limits3, ProgramService};
use motus_gcode::InterpreterConfig;
use motus_station_web::ProgramInfo;

use crate::lock;

/// Programs by id, and the service that runs them.
pub(crate) struct Programs {
    pub(crate) store: Mutex<BTreeMap<String, (ProgramInfo, String)>>,
    pub(crate) service: ProgramService,
    pub(crate) running: Mutex<Option<String>>,
}

impl Programs {
    pub(crate) fn start() -> std::io::Result<Self> {
        Ok(Self {
            store: Mutex::new(BTreeMap::new()),
            service: ProgramService::start(Limits3::default(), InterpreterConfig::default(), None)?,
            running: Mutex::new(None),
        })
    }

    pub(crate) fn add(&self, owner: &str, name: &str, text: &str) -> ProgramInfo {
        let mut store = lock(&self.store);
        let base: String = name
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() || c == '.' || c == '-' { c } else { '_' })
            .collect();
        let mut id = base.clone();
        let mut k = 1;
        while store.contains_key(&id) {
            k += 1;
            id = format!("{base}-{k}");
        }
        let info = ProgramInfo {
            id: id.clone(),
            name: name.to_owned(),
            owner: owner.to_owned(),
            size: text.len() as u64,
            lines: text.lines().count(),
        };
        store.insert(id, (info.clone(), text.to_owned()));
        info
    }
}

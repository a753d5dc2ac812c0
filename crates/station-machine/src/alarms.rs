//! The runtime's alarms (device disconnected, cycle overrun...) in the lab's alarm store, so
//! the HMI and `GET /api/alarms` show them with time stamps, acknowledgement and history.
//!
//! [`AlarmSink`] is called from cyclic threads and must not block: [`LabAlarmSink`] queues
//! each event and one thread writes them to the store.

use std::sync::mpsc::{channel, Sender};
use std::sync::{Arc, Mutex};
use std::time::SystemTime;

use motus_lab::{Lab, Severity, UnixMs};
use motus_station::alarm::{Alarm, AlarmCode, AlarmSeverity, AlarmSink};

enum Event {
    Raise(Alarm),
    Clear(String, AlarmCode),
}

/// Forwards alarms to a [`Lab`]'s store from its own thread.
pub struct LabAlarmSink {
    tx: Mutex<Sender<Event>>,
}

impl LabAlarmSink {
    /// Starts the writer thread (it ends when the sink is dropped).
    ///
    /// # Errors
    /// The thread cannot be started.
    pub fn start(lab: Arc<Lab>) -> std::io::Result<Arc<Self>> {
        let (tx, rx) = channel::<Event>();
        std::thread::Builder::new().name("motus-alarms".into()).spawn(move || {
            for event in rx {
                let now = UnixMs::from(SystemTime::now());
                let r = match &event {
                    Event::Raise(a) => {
                        let severity = match a.severity {
                            AlarmSeverity::Info => Severity::Info,
                            AlarmSeverity::Warning => Severity::Warning,
                            AlarmSeverity::Error => Severity::Error,
                        };
                        lab.alarms().raise(a.code.as_str(), &a.source, &a.message, severity, now).map(|_| ())
                    }
                    Event::Clear(source, code) => lab.alarms().clear(code.as_str(), source, now).map(|_| ()),
                };
                if let Err(e) = r {
                    tracing::error!(error = %e, "cannot store an alarm");
                }
            }
        })?;
        Ok(Arc::new(Self { tx: Mutex::new(tx) }))
    }

    fn send(&self, event: Event) {
        if let Ok(tx) = self.tx.lock() {
            let _ = tx.send(event);
        }
    }
}

impl AlarmSink for LabAlarmSink {
    fn raise(&self, alarm: Alarm) {
        self.send(Event::Raise(alarm));
    }

    fn clear(&self, source: &str, code: AlarmCode) {
        self.send(Event::Clear(source.to_owned(), code));
    }
}

/// Every alarm to each of several sinks.
pub(crate) struct Tee(pub(crate) Vec<Arc<dyn AlarmSink>>);

impl AlarmSink for Tee {
    fn raise(&self, alarm: Alarm) {
        for s in &self.0 {
            s.raise(alarm.clone());
        }
    }

    fn clear(&self, source: &str, code: AlarmCode) {
        for s in &self.0 {
            s.clear(source, code);
        }
    }
}

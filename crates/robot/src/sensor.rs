//! Reads the optical-mouse converter (7-byte packets at 9600 bit/s) from a serial line
//! into the controller's sensor input.

use motus_mouse_protocol::{ConverterPacket, PacketScanner};
use motus_omni::controller::SensorInput;
use motus_serial::{FramedLink, SerialLink};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

/// A running sensor reader; stops on drop.
pub struct SensorReader {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl SensorReader {
    /// Opens the serial port at `path` (9600 8N1) and feeds every packet's counts to
    /// `input`. Garbage between packets is skipped by the resynchronising decoder.
    pub fn start(path: &str, input: Arc<SensorInput>) -> std::io::Result<SensorReader> {
        let link = SerialLink::open(path, 9600)?;
        let mut sensor = FramedLink::new(Box::new(link), PacketScanner::<ConverterPacket>::default());
        let stop = Arc::new(AtomicBool::new(false));
        let s = Arc::clone(&stop);
        let thread = std::thread::Builder::new().name("mouse-reader".into()).spawn(move || {
            motus_realtime::promote_current_thread(motus_realtime::ThreadClass::Device);
            while !s.load(Ordering::Relaxed) {
                match sensor.receive(Duration::from_millis(20)) {
                    Ok(Some(p)) if p.device.is_mouse() => input.add_counts(i32::from(p.dx), i32::from(p.dy)),
                    Ok(_) => {}
                    Err(e) => {
                        tracing::warn!(error = %e, "mouse sensor read failed");
                        std::thread::sleep(Duration::from_millis(50));
                    }
                }
            }
        })?;
        Ok(SensorReader { stop, thread: Some(thread) })
    }
}

impl Drop for SensorReader {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

//! Reads the optical-mouse converter (7-byte packets at 9600 bit/s) from a serial line
//! into the controller's sensor input.

use motus_clock::{SharedClock, SystemClock};
use motus_mouse_protocol::{ConverterPacket, PacketScanner};
use motus_omni::controller::SensorInput;
use motus_serial::{FramedLink, Link, SerialLink};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

/// A running sensor reader; stops on drop.
pub struct SensorReader {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    clock: SharedClock,
}

impl SensorReader {
    /// Opens the serial port at `path` (9600 8N1) and feeds every packet's counts to
    /// `input`. Garbage between packets is skipped by the resynchronising decoder.
    pub fn start(path: &str, input: Arc<SensorInput>) -> std::io::Result<SensorReader> {
        let link = SerialLink::open(path, 9600)?;
        Self::start_on(Box::new(link), input, SystemClock::shared())
    }

    /// Reads the converter's packets from `link` (any [`Link`]: a serial port, or an
    /// in-process line in tests) with its time-outs on `clock`; the reading thread takes
    /// part in the clock ([`motus_clock::spawn`]), so on a threaded virtual clock the
    /// counts reach `input` at the virtual instant their packet is complete.
    pub fn start_on(
        link: Box<dyn Link>,
        input: Arc<SensorInput>,
        clock: SharedClock,
    ) -> std::io::Result<SensorReader> {
        let mut sensor =
            FramedLink::with_clock(link, PacketScanner::<ConverterPacket>::default(), Arc::clone(&clock));
        let stop = Arc::new(AtomicBool::new(false));
        let s = Arc::clone(&stop);
        let thread_clock = Arc::clone(&clock);
        let builder = std::thread::Builder::new().name("mouse-reader".into());
        let thread = motus_clock::spawn(&clock, builder, move || {
            motus_realtime::promote_current_thread(motus_realtime::ThreadClass::Device);
            while !s.load(Ordering::Relaxed) {
                match sensor.receive(Duration::from_millis(20)) {
                    Ok(Some(p)) if p.device.is_mouse() => input.add_counts(i32::from(p.dx), i32::from(p.dy)),
                    Ok(_) => {}
                    Err(e) => {
                        tracing::warn!(error = %e, "mouse sensor read failed");
                        thread_clock.sleep(Duration::from_millis(50));
                    }
                }
            }
        })?;
        Ok(SensorReader { stop, thread: Some(thread), clock })
    }
}

impl Drop for SensorReader {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = motus_clock::while_blocked(&*self.clock, || t.join());
        }
    }
}

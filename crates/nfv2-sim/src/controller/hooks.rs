//! Test hooks: the world around the controller (its inputs, the axis, the supply), set by a
//! test or a fault-injection script. A change takes effect at the next regulator cycle
//! (ENABLE switches the bridge off from the first substep of that cycle).

use super::Controller;
use crate::error::SimError;
use crate::inputs::{Inputs, LimitSwitch, ANALOG_FULL_SCALE_V};

fn finite(value: f64, what: &'static str) -> Result<f64, SimError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(SimError::NotFinite { what })
    }
}

impl Controller {
    /// Connects (`true`) or breaks (`false`) the ENABLE input, the emergency-stop loop.
    pub fn set_enable(&mut self, present: bool) {
        self.inputs.enable = present;
    }

    /// Forces `switch` closed (`Some(true)`) or open (`Some(false)`), or lets it follow the
    /// axis position again (`None`).
    pub fn set_limit_switch(&mut self, switch: LimitSwitch, forced: Option<bool>) {
        if let Some(slot) = self.inputs.limit_forced.get_mut(Inputs::slot(switch)) {
            *slot = forced;
        }
    }

    /// Moves a limit switch: it closes at and beyond `counts` (true position), or never
    /// (`None`).
    ///
    /// # Errors
    /// [`SimError::NotFinite`] for a NaN or infinite position.
    pub fn set_limit_switch_position(
        &mut self,
        switch: LimitSwitch,
        counts: Option<f64>,
    ) -> Result<(), SimError> {
        let counts = counts.map(|c| finite(c, "limit switch position")).transpose()?;
        if let Some(slot) = self.inputs.limit_positions.get_mut(Inputs::slot(switch)) {
            *slot = counts;
        }
        Ok(())
    }

    /// Places the HOME sensor's edge: HOME is active at and below `counts` (true position),
    /// or never (`None`).
    ///
    /// # Errors
    /// [`SimError::NotFinite`] for a NaN or infinite position.
    pub fn set_home_edge(&mut self, counts: Option<f64>) -> Result<(), SimError> {
        self.inputs.home_edge = counts.map(|c| finite(c, "home edge")).transpose()?;
        Ok(())
    }

    /// Sets analog input `index` (0: AI0, 1: AI1) to `volts`, clamped to the 0..30 V range.
    ///
    /// # Errors
    /// [`SimError::NoSuchAnalogInput`], [`SimError::NotFinite`].
    pub fn set_analog_input(&mut self, index: usize, volts: f64) -> Result<(), SimError> {
        let volts = finite(volts, "analog input voltage")?.clamp(0.0, ANALOG_FULL_SCALE_V);
        let slot = self.inputs.analog_v.get_mut(index).ok_or(SimError::NoSuchAnalogInput(index))?;
        *slot = volts;
        Ok(())
    }

    /// Sets the power-stage supply (PSUPP) to `volts`; below `power_stage_low_v` the power
    /// stage is off and status bit 9 is set.
    ///
    /// # Errors
    /// [`SimError::NotFinite`].
    pub fn set_power_stage_supply(&mut self, volts: f64) -> Result<(), SimError> {
        self.inputs.supply_v = finite(volts, "power-stage supply")?.max(0.0);
        Ok(())
    }

    /// Cuts the power-stage supply (0 V).
    pub fn cut_power_stage(&mut self) {
        self.inputs.supply_v = 0.0;
    }

    /// Restores the nominal power-stage supply.
    pub fn restore_power_stage(&mut self) {
        self.inputs.supply_v = self.config.supply_v;
    }

    /// Moves the axis by hand to `counts` (true position), at rest. The counter follows
    /// the encoder; in a position-loop mode the regulators will pull the axis back to
    /// their reference, so use it in ERROR.
    ///
    /// # Errors
    /// [`SimError::NotFinite`].
    pub fn place_axis(&mut self, counts: f64) -> Result<(), SimError> {
        self.motor.place(finite(counts, "axis position")?);
        self.counter = self.motor.counts().floor() as i64 + self.counter_offset;
        self.history = [self.counter; super::SPEED_WINDOW + 1];
        self.measured_speed = 0.0;
        Ok(())
    }

    /// The digital outputs as last set (GO0..GO3 bits 0-3, +O4 bit 4, fan bit 5).
    #[must_use]
    pub fn digital_outputs(&self) -> u8 {
        self.inputs.digital_outputs
    }
}

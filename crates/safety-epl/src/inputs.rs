//! From PRes payloads to supervisor samples.

use motus_epl_protocol::{Value, ValueMap};
use motus_safety::{RuleSet, Sample};
use thiserror::Error;

/// The map cannot feed the rules.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum InputError {
    /// An axis id is not a POWERLINK CN node ID.
    #[error("axis {axis}: id {id} is not a controlled-node ID (1..=239)")]
    NotANode {
        /// Axis name.
        axis: String,
        /// Its id.
        id: u32,
    },
    /// The value map lacks the node of an axis or one of its values.
    #[error("axis {axis}: the value map has no {what} for node {node}")]
    Missing {
        /// Axis name.
        axis: String,
        /// Node.
        node: u8,
        /// What is missing.
        what: &'static str,
    },
}

#[derive(Debug, Clone)]
struct AxisInput {
    node: u8,
    raw_per_unit: f64,
    position: usize,
    speed: usize,
    status: Option<usize>,
}

/// Where each supervised axis's values are in which node's PRes.
#[derive(Debug, Clone)]
pub struct InputMap {
    map: ValueMap,
    axes: Vec<AxisInput>,
    homed_mask: u16,
}

impl InputMap {
    /// Builds the mapping for `rules` from a value map. Each axis's node is its `id`; the
    /// node must map `position` and `speed`, and may map `status`, whose `homed_mask` bits
    /// say the axis is homed (without `status` an axis counts as homed: absolute encoder).
    pub fn new(rules: &RuleSet, map: ValueMap, homed_mask: u16) -> Result<Self, InputError> {
        let mut axes = Vec::new();
        for a in rules.axes() {
            let node = u8::try_from(a.id)
                .ok()
                .filter(|n| (1..=239).contains(n))
                .ok_or_else(|| InputError::NotANode { axis: a.name.clone(), id: a.id })?;
            let nv =
                map.node(node).ok_or(InputError::Missing { axis: a.name.clone(), node, what: "entry" })?;
            let find = |name: &str| nv.values.iter().position(|v| v.name == name);
            let position = find("position").ok_or(InputError::Missing {
                axis: a.name.clone(),
                node,
                what: "position",
            })?;
            let speed =
                find("speed").ok_or(InputError::Missing { axis: a.name.clone(), node, what: "speed" })?;
            axes.push(AxisInput {
                node,
                raw_per_unit: a.raw_per_unit,
                position,
                speed,
                status: find("status"),
            });
        }
        Ok(Self { map, axes, homed_mask })
    }

    /// The value map.
    pub fn value_map(&self) -> &ValueMap {
        &self.map
    }

    /// Axis indices (rules order) fed by `node`.
    pub fn axes_of(&self, node: u8) -> impl Iterator<Item = usize> + '_ {
        self.axes.iter().enumerate().filter(move |(_, a)| a.node == node).map(|(i, _)| i)
    }

    /// The sample of axis `index` from a PRes payload of its node, stamped with `cycle`;
    /// `None` when the payload is too short for the mapped values (the axis then goes stale).
    pub fn sample(&self, index: usize, payload: &[u8], cycle: u64) -> Option<Sample> {
        let a = self.axes.get(index)?;
        let nv = self.map.node(a.node)?;
        let read = |i: usize| nv.values.get(i).and_then(|v| v.read(a.node, payload).ok());
        let position = read(a.position)?.as_f64() / a.raw_per_unit;
        let speed = read(a.speed)?.as_f64() / a.raw_per_unit;
        let homed = match a.status {
            None => true,
            Some(i) => match read(i)? {
                Value::U16(s) => s & self.homed_mask == self.homed_mask,
                other => (other.as_f64() as u32) & u32::from(self.homed_mask) == u32::from(self.homed_mask),
            },
        };
        Some(Sample { position, speed, cycle, homed })
    }
}

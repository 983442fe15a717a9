//! The RTDE inputs of the simulated controller: name -> type, current value, which connection
//! holds it. The output tables (`fields`) read them back; the controller
//! (`robot`) and the control loops write them.

use ur5e::rtde::{RtdeType, RtdeValue};

/// Connection id that holds an input (for `IN_USE`).
pub type ConnectionId = u64;

/// One RTDE input variable.
#[derive(Debug, Clone, PartialEq)]
pub struct InputSlot {
    /// Name.
    pub name: String,
    /// Type.
    pub ty: RtdeType,
    /// Last value received.
    pub value: RtdeValue,
    /// Connection that set it up.
    pub holder: Option<ConnectionId>,
    /// Controller time of the last update (s).
    pub updated_at_s: Option<f64>,
}

/// All RTDE inputs of the controller.
#[derive(Debug, Clone, PartialEq)]
pub struct InputTable {
    pub(crate) slots: Vec<InputSlot>,
}

impl Default for InputTable {
    fn default() -> Self {
        Self::new()
    }
}

impl InputTable {
    /// The inputs of PolyScope 5 (reference §2.6 "Inputs").
    pub fn new() -> Self {
        let mut slots = Vec::new();
        let mut add = |name: String, ty: RtdeType| {
            slots.push(InputSlot {
                name,
                ty,
                value: RtdeValue::zero(ty),
                holder: None,
                updated_at_s: None,
            })
        };
        add("speed_slider_mask".into(), RtdeType::Uint32);
        add("speed_slider_fraction".into(), RtdeType::Double);
        for n in [
            "standard_digital_output_mask",
            "standard_digital_output",
            "configurable_digital_output_mask",
            "configurable_digital_output",
            "tool_digital_output_mask",
            "tool_digital_output",
            "standard_analog_output_mask",
            "standard_analog_output_type",
        ] {
            add(n.into(), RtdeType::Uint8);
        }
        add("standard_analog_output_0".into(), RtdeType::Double);
        add("standard_analog_output_1".into(), RtdeType::Double);
        add("input_bit_registers0_to_31".into(), RtdeType::Uint32);
        add("input_bit_registers32_to_63".into(), RtdeType::Uint32);
        for i in 64..=127 {
            add(format!("input_bit_register_{i}"), RtdeType::Bool);
        }
        for i in 0..=47 {
            add(format!("input_int_register_{i}"), RtdeType::Int32);
        }
        for i in 0..=47 {
            add(format!("input_double_register_{i}"), RtdeType::Double);
        }
        add("external_force_torque".into(), RtdeType::Vector6d);
        Self { slots }
    }

    /// Slot index of an input name.
    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.slots.iter().position(|s| s.name == name)
    }

    /// Slot by index.
    pub fn slot(&self, index: usize) -> &InputSlot {
        &self.slots[index]
    }

    /// Current value of a slot.
    pub fn value(&self, index: usize) -> RtdeValue {
        self.slots[index].value
    }

    /// When a slot was last written (controller time).
    pub fn updated_at_s(&self, index: usize) -> Option<f64> {
        self.slots[index].updated_at_s
    }

    /// Claims slots for a connection; returns per-slot whether it is held by another one.
    /// Claims nothing if any slot is in use (the recipe is then refused as a whole).
    pub fn claim(&mut self, indices: &[usize], conn: ConnectionId) -> Vec<bool> {
        let in_use: Vec<bool> = indices
            .iter()
            .map(|&i| self.slots[i].holder.is_some_and(|h| h != conn))
            .collect();
        if !in_use.iter().any(|&b| b) {
            for &i in indices {
                self.slots[i].holder = Some(conn);
            }
        }
        in_use
    }

    /// Releases every slot a closed connection held.
    pub fn release(&mut self, conn: ConnectionId) {
        for s in &mut self.slots {
            if s.holder == Some(conn) {
                s.holder = None;
            }
        }
    }

    /// Writes a value received at controller time `now_s`.
    pub fn write(&mut self, index: usize, value: RtdeValue, now_s: f64) {
        let slot = &mut self.slots[index];
        slot.value = value;
        slot.updated_at_s = Some(now_s);
    }

    /// Marks a slot updated without changing it (tests of the watchdog).
    pub fn mark_updated(&mut self, index: usize, now_s: f64) {
        self.slots[index].updated_at_s = Some(now_s);
    }
}

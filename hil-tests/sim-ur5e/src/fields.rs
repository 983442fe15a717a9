//! RTDE variable tables of the simulated controller: outputs (name -> type -> value from a
//! [`Snapshot`]) and inputs (name -> type, current value, which connection holds it).
//!
//! Types follow G-RTDE / URCL's name table (reference §2.6): ur_rtde decodes by its own table,
//! so every type here must be the official one or its parsing misaligns.

use ur5e::rtde::{RtdeType, RtdeValue};

use crate::robot::Snapshot;

/// Where an output value comes from.
#[derive(Debug, Clone, Copy)]
pub enum OutputSource {
    /// A fixed field computed from the snapshot.
    Fixed(fn(&Snapshot, &InputTable) -> RtdeValue),
    /// Read-back of an input slot.
    Input(usize),
    /// Always zero (bit registers: no program writes them in this simulator).
    Zero,
    /// `output_int_register_n` (written by ur_rtde's control loop).
    IntRegister(usize),
    /// `output_double_register_n`.
    DoubleRegister(usize),
}

/// One resolved output variable.
#[derive(Debug, Clone, Copy)]
pub struct OutputField {
    /// Its type.
    pub ty: RtdeType,
    /// Its value source.
    pub source: OutputSource,
}

impl OutputField {
    /// The value for this cycle.
    pub fn value(&self, snap: &Snapshot, inputs: &InputTable) -> RtdeValue {
        match self.source {
            OutputSource::Fixed(f) => f(snap, inputs),
            OutputSource::Input(i) => inputs.value(i),
            OutputSource::Zero => RtdeValue::zero(self.ty),
            OutputSource::IntRegister(n) => {
                RtdeValue::Int32(snap.output_int_registers.get(n).copied().unwrap_or(0))
            }
            OutputSource::DoubleRegister(n) => {
                RtdeValue::Double(snap.output_double_registers.get(n).copied().unwrap_or(0.0))
            }
        }
    }
}

type Getter = fn(&Snapshot, &InputTable) -> RtdeValue;

fn v6(x: [f64; 6]) -> RtdeValue {
    RtdeValue::Vector6d(x)
}

/// Fixed output variables. Electrical and thermal values are plausible constants.
static FIXED_OUTPUTS: &[(&str, RtdeType, Getter)] = &[
    ("timestamp", RtdeType::Double, |s, _| {
        RtdeValue::Double(s.time_s)
    }),
    ("target_q", RtdeType::Vector6d, |s, _| v6(s.target_q)),
    ("target_qd", RtdeType::Vector6d, |s, _| v6(s.qd)),
    ("target_qdd", RtdeType::Vector6d, |s, _| v6(s.qdd)),
    ("target_current", RtdeType::Vector6d, |_, _| v6([0.0; 6])),
    ("target_moment", RtdeType::Vector6d, |_, _| v6([0.0; 6])),
    ("actual_q", RtdeType::Vector6d, |s, _| v6(s.q)),
    ("actual_qd", RtdeType::Vector6d, |s, _| v6(s.qd)),
    ("actual_current", RtdeType::Vector6d, |_, _| v6([0.0; 6])),
    ("actual_current_as_torque", RtdeType::Vector6d, |_, _| {
        v6([0.0; 6])
    }),
    ("joint_control_output", RtdeType::Vector6d, |_, _| {
        v6([0.0; 6])
    }),
    ("actual_TCP_pose", RtdeType::Vector6d, |s, _| v6(s.tcp_pose)),
    ("actual_TCP_speed", RtdeType::Vector6d, |s, _| {
        v6(s.tcp_speed)
    }),
    ("actual_TCP_force", RtdeType::Vector6d, |_, _| v6([0.0; 6])),
    ("target_TCP_pose", RtdeType::Vector6d, |s, _| v6(s.tcp_pose)),
    ("target_TCP_speed", RtdeType::Vector6d, |s, _| {
        v6(s.tcp_speed)
    }),
    ("actual_digital_input_bits", RtdeType::Uint64, |_, _| {
        RtdeValue::Uint64(0)
    }),
    ("actual_digital_output_bits", RtdeType::Uint64, |s, _| {
        RtdeValue::Uint64(s.digital_output_bits)
    }),
    ("joint_temperatures", RtdeType::Vector6d, |_, _| {
        v6([35.0; 6])
    }),
    ("actual_execution_time", RtdeType::Double, |_, _| {
        RtdeValue::Double(0.2)
    }),
    ("robot_mode", RtdeType::Int32, |s, _| {
        RtdeValue::Int32(s.robot_mode)
    }),
    ("joint_mode", RtdeType::Vector6Int32, |s, _| {
        RtdeValue::Vector6Int32([s.joint_mode(); 6])
    }),
    ("safety_mode", RtdeType::Int32, |s, _| {
        RtdeValue::Int32(s.safety_mode)
    }),
    ("safety_status", RtdeType::Int32, |s, _| {
        RtdeValue::Int32(s.safety_mode)
    }),
    ("actual_tool_accelerometer", RtdeType::Vector3d, |_, _| {
        RtdeValue::Vector3d([0.0, 0.0, -9.81])
    }),
    ("speed_scaling", RtdeType::Double, |s, _| {
        RtdeValue::Double(s.speed_scaling)
    }),
    ("target_speed_fraction", RtdeType::Double, |s, _| {
        RtdeValue::Double(s.target_speed_fraction)
    }),
    ("actual_momentum", RtdeType::Double, |_, _| {
        RtdeValue::Double(0.0)
    }),
    ("actual_main_voltage", RtdeType::Double, |_, _| {
        RtdeValue::Double(48.0)
    }),
    ("actual_robot_voltage", RtdeType::Double, |_, _| {
        RtdeValue::Double(48.0)
    }),
    ("actual_robot_current", RtdeType::Double, |_, _| {
        RtdeValue::Double(0.5)
    }),
    ("actual_joint_voltage", RtdeType::Vector6d, |_, _| {
        v6([48.0; 6])
    }),
    ("runtime_state", RtdeType::Uint32, |s, _| {
        RtdeValue::Uint32(s.runtime_state)
    }),
    ("elbow_position", RtdeType::Vector3d, |s, _| {
        RtdeValue::Vector3d(s.elbow_position)
    }),
    ("elbow_velocity", RtdeType::Vector3d, |_, _| {
        RtdeValue::Vector3d([0.0; 3])
    }),
    ("robot_status_bits", RtdeType::Uint32, |s, _| {
        RtdeValue::Uint32(s.robot_status_bits())
    }),
    ("safety_status_bits", RtdeType::Uint32, |s, _| {
        RtdeValue::Uint32(s.safety_status_bits())
    }),
    ("analog_io_types", RtdeType::Uint32, |_, _| {
        RtdeValue::Uint32(0)
    }),
    ("standard_analog_input0", RtdeType::Double, |_, _| {
        RtdeValue::Double(0.0)
    }),
    ("standard_analog_input1", RtdeType::Double, |_, _| {
        RtdeValue::Double(0.0)
    }),
    ("standard_analog_output0", RtdeType::Double, |_, _| {
        RtdeValue::Double(0.0)
    }),
    ("standard_analog_output1", RtdeType::Double, |_, _| {
        RtdeValue::Double(0.0)
    }),
    ("io_current", RtdeType::Double, |_, _| {
        RtdeValue::Double(0.0)
    }),
    ("euromap67_input_bits", RtdeType::Uint32, |_, _| {
        RtdeValue::Uint32(0)
    }),
    ("euromap67_output_bits", RtdeType::Uint32, |_, _| {
        RtdeValue::Uint32(0)
    }),
    ("euromap67_24V_voltage", RtdeType::Double, |_, _| {
        RtdeValue::Double(0.0)
    }),
    ("euromap67_24V_current", RtdeType::Double, |_, _| {
        RtdeValue::Double(0.0)
    }),
    ("tool_mode", RtdeType::Uint32, |_, _| RtdeValue::Uint32(0)),
    ("tool_analog_input_types", RtdeType::Uint32, |_, _| {
        RtdeValue::Uint32(0)
    }),
    ("tool_analog_input0", RtdeType::Double, |_, _| {
        RtdeValue::Double(0.0)
    }),
    ("tool_analog_input1", RtdeType::Double, |_, _| {
        RtdeValue::Double(0.0)
    }),
    ("tool_output_voltage", RtdeType::Int32, |_, _| {
        RtdeValue::Int32(24)
    }),
    ("tool_output_current", RtdeType::Double, |_, _| {
        RtdeValue::Double(0.0)
    }),
    ("tool_temperature", RtdeType::Double, |_, _| {
        RtdeValue::Double(35.0)
    }),
    ("tool_output_mode", RtdeType::Uint8, |_, _| {
        RtdeValue::Uint8(0)
    }),
    ("tool_digital_output0_mode", RtdeType::Uint8, |_, _| {
        RtdeValue::Uint8(0)
    }),
    ("tool_digital_output1_mode", RtdeType::Uint8, |_, _| {
        RtdeValue::Uint8(0)
    }),
    ("tcp_force_scalar", RtdeType::Double, |_, _| {
        RtdeValue::Double(0.0)
    }),
    ("payload", RtdeType::Double, |_, _| RtdeValue::Double(0.0)),
    ("payload_cog", RtdeType::Vector3d, |_, _| {
        RtdeValue::Vector3d([0.0; 3])
    }),
    ("payload_inertia", RtdeType::Vector6d, |_, _| v6([0.0; 6])),
    ("script_control_line", RtdeType::Uint32, |_, _| {
        RtdeValue::Uint32(0)
    }),
    ("ft_raw_wrench", RtdeType::Vector6d, |_, _| v6([0.0; 6])),
    ("output_bit_registers0_to_31", RtdeType::Uint32, |_, _| {
        RtdeValue::Uint32(0)
    }),
    ("output_bit_registers32_to_63", RtdeType::Uint32, |_, _| {
        RtdeValue::Uint32(0)
    }),
];

/// Parses `<prefix><n>` with `n` in `range`.
fn register(name: &str, prefix: &str, range: core::ops::RangeInclusive<u32>) -> Option<u32> {
    let n: u32 = name.strip_prefix(prefix)?.parse().ok()?;
    range.contains(&n).then_some(n)
}

/// Resolves an output variable name; `None` = `NOT_FOUND`.
pub fn resolve_output(name: &str, inputs: &InputTable) -> Option<OutputField> {
    if let Some((_, ty, f)) = FIXED_OUTPUTS.iter().find(|(n, _, _)| *n == name) {
        return Some(OutputField {
            ty: *ty,
            source: OutputSource::Fixed(*f),
        });
    }
    let zero = |ty| {
        Some(OutputField {
            ty,
            source: OutputSource::Zero,
        })
    };
    if register(name, "output_bit_register_", 64..=127).is_some() {
        return zero(RtdeType::Bool);
    }
    if let Some(n) = register(name, "output_int_register_", 0..=47) {
        return Some(OutputField {
            ty: RtdeType::Int32,
            source: OutputSource::IntRegister(n as usize),
        });
    }
    if let Some(n) = register(name, "output_double_register_", 0..=47) {
        return Some(OutputField {
            ty: RtdeType::Double,
            source: OutputSource::DoubleRegister(n as usize),
        });
    }
    // Input variables can be read back as outputs.
    inputs.index_of(name).map(|i| OutputField {
        ty: inputs.slots[i].ty,
        source: OutputSource::Input(i),
    })
}

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
    slots: Vec<InputSlot>,
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ur_rtde_receive_defaults_resolve_with_official_types() {
        let inputs = InputTable::new();
        // The names RTDEReceiveInterface asks for at 5.21 (reference §2.8.1), with their types.
        let expect = [
            ("timestamp", RtdeType::Double),
            ("joint_mode", RtdeType::Vector6Int32),
            ("actual_tool_accelerometer", RtdeType::Vector3d),
            ("actual_digital_input_bits", RtdeType::Uint64),
            ("runtime_state", RtdeType::Uint32),
            ("robot_mode", RtdeType::Int32),
            ("payload_cog", RtdeType::Vector3d),
            ("payload_inertia", RtdeType::Vector6d),
            ("ft_raw_wrench", RtdeType::Vector6d),
            ("output_int_register_12", RtdeType::Int32),
            ("output_double_register_19", RtdeType::Double),
            ("input_int_register_24", RtdeType::Int32),
        ];
        for (name, ty) in expect {
            assert_eq!(
                resolve_output(name, &inputs).map(|f| f.ty),
                Some(ty),
                "{name}"
            );
        }
        assert!(resolve_output("output_int_register_48", &inputs).is_none());
        assert!(resolve_output("no_such_thing", &inputs).is_none());
    }

    #[test]
    fn inputs_conflict_only_between_connections_and_are_released() {
        let mut t = InputTable::new();
        let r = t.index_of("input_int_register_24").unwrap();
        assert_eq!(t.claim(&[r], 1), [false]);
        assert_eq!(
            t.claim(&[r], 1),
            [false],
            "same connection may list it again"
        );
        assert_eq!(t.claim(&[r], 2), [true]);
        t.release(1);
        assert_eq!(t.claim(&[r], 2), [false]);
    }
}

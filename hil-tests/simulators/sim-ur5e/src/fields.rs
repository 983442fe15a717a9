//! RTDE variable tables of the simulated controller: outputs (name -> type -> value from a
//! [`Snapshot`]) and inputs as outputs (the inputs themselves, name -> type, current value,
//! which connection holds it, are [`crate::inputs`]).
//!
//! Types follow G-RTDE / URCL's name table (reference §2.6): ur_rtde decodes by its own table,
//! so every type here must be the official one or its parsing misaligns.

use ur5e::rtde::{RtdeType, RtdeValue};

pub use crate::inputs::{ConnectionId, InputSlot, InputTable};
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

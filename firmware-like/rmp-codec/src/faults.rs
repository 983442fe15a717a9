//! RMP v3 fault status words 1..4 (reference §2.8): how they pack the fault groups, and the
//! names of the bits a host acts on.

/// One named fault bit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FaultBit {
    /// Fault status word (0-based: 0 = FSW 1).
    pub word: u8,
    /// Mask within that word.
    pub mask: u32,
    /// Short name for logs and error messages.
    pub name: &'static str,
}

const fn bit(word: u8, mask: u32, name: &'static str) -> FaultBit {
    FaultBit { word, mask, name }
}

/// FSW 1 bits 0..11: architecture faults.
pub const ARCHITECTURE_MASK: u32 = 0x0000_0FFF;
/// FSW 1 bits 12..31: critical (latching) faults.
pub const CRITICAL_MASK: u32 = 0xFFFF_F000;
/// FSW 2 bits 0..15: communication faults.
pub const COMMUNICATION_MASK: u32 = 0x0000_FFFF;
/// FSW 2 bits 16..19: internal faults.
pub const INTERNAL_MASK: u32 = 0x000F_0000;

/// Architecture: commanded safety shutdown.
pub const COMMANDED_SAFETY_SHUTDOWN: FaultBit = bit(0, 0x010, "commanded safety shutdown");
/// Architecture: commanded disable.
pub const COMMANDED_DISABLE: FaultBit = bit(0, 0x020, "commanded disable");
/// Architecture: kill switch active.
pub const KILL_SWITCH_ACTIVE: FaultBit = bit(0, 0x040, "kill switch active");
/// Architecture: decel switch active (SEGPY naming).
pub const DECEL_SWITCH_ACTIVE: FaultBit = bit(0, 0x800, "decel switch active");
/// Critical: velocity control failed.
pub const VELOCITY_CONTROL_FAILED: FaultBit = bit(0, 0x80 << 12, "velocity control failed");
/// Critical: position control failed.
pub const POSITION_CONTROL_FAILED: FaultBit = bit(0, 0x100 << 12, "position control failed");
/// Critical: forward speed-limiter hazard.
pub const FORWARD_SPEED_LIMITER_HAZARD: FaultBit =
    bit(0, 0x10 << 12, "forward speed limiter hazard");
/// Communication: bad motion command.
pub const BAD_MOTION_COMMAND: FaultBit = bit(1, 0x10, "bad motion command");
/// Communication: unknown command.
pub const UNKNOWN_COMMAND: FaultBit = bit(1, 0x20, "unknown command");
/// Communication: unknown message received.
pub const UNKNOWN_MESSAGE: FaultBit = bit(1, 0x02, "unknown message received");

/// Named bits, in word order, for describing a fault state.
pub const NAMED_BITS: [FaultBit; 31] = [
    bit(0, 0x001, "SPI receive"),
    bit(0, 0x002, "SPI transmit"),
    bit(0, 0x004, "SPI receive overrun"),
    bit(0, 0x008, "SPI RX buffer overrun"),
    COMMANDED_SAFETY_SHUTDOWN,
    COMMANDED_DISABLE,
    KILL_SWITCH_ACTIVE,
    bit(0, 0x080, "F-RAM config init failed"),
    bit(0, 0x100, "F-RAM config set failed"),
    bit(0, 0x200, "bad model identifier"),
    bit(0, 0x400, "bad CCU hardware revision"),
    DECEL_SWITCH_ACTIVE,
    bit(0, 0x1 << 12, "init"),
    bit(0, 0x2 << 12, "init UIP comm"),
    bit(0, 0x4 << 12, "init propulsion"),
    bit(0, 0x8 << 12, "init timeout"),
    FORWARD_SPEED_LIMITER_HAZARD,
    bit(0, 0x20 << 12, "aft speed limiter hazard"),
    bit(0, 0x40 << 12, "check start-up"),
    VELOCITY_CONTROL_FAILED,
    POSITION_CONTROL_FAILED,
    bit(0, 0x200 << 12, "ABB shutdown"),
    bit(0, 0x400 << 12, "AP mode transition timeout"),
    bit(0, 0x800 << 12, "pitch angle exceeded"),
    bit(0, 0x1000 << 12, "roll angle exceeded"),
    bit(1, 0x01, "missing UIP data"),
    UNKNOWN_MESSAGE,
    bit(1, 0x04, "UIP bad checksum"),
    bit(1, 0x08, "UIP transmit"),
    BAD_MOTION_COMMAND,
    UNKNOWN_COMMAND,
];

/// Fault status words 1..4 as reported.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub struct FaultStatus {
    words: [u32; 4],
}

impl FaultStatus {
    /// No fault.
    pub const CLEAR: Self = Self { words: [0; 4] };

    /// From FSW 1..4.
    pub const fn new(words: [u32; 4]) -> Self {
        Self { words }
    }

    /// FSW 1..4.
    pub const fn words(&self) -> [u32; 4] {
        self.words
    }

    /// True when `fault` is set.
    pub const fn has(&self, fault: FaultBit) -> bool {
        self.words[fault.word as usize] & fault.mask != 0
    }

    /// Sets `fault` (simulator side).
    pub fn set(&mut self, fault: FaultBit) {
        self.words[fault.word as usize] |= fault.mask;
    }

    /// Clears `fault` (simulator side).
    pub fn clear(&mut self, fault: FaultBit) {
        self.words[fault.word as usize] &= !fault.mask;
    }

    /// Architecture-fault bits (FSW 1 bits 0..11).
    pub const fn architecture(&self) -> u32 {
        self.words[0] & ARCHITECTURE_MASK
    }

    /// Critical-fault group (FSW 1 bits 12..31 shifted down: bit b = critical fault b).
    pub const fn critical(&self) -> u32 {
        (self.words[0] & CRITICAL_MASK) >> 12
    }

    /// Communication-fault bits (FSW 2 bits 0..15).
    pub const fn communication(&self) -> u32 {
        self.words[1] & COMMUNICATION_MASK
    }

    /// Internal-fault group (FSW 2 bits 16..19 shifted down).
    pub const fn internal(&self) -> u32 {
        (self.words[1] & INTERNAL_MASK) >> 16
    }

    /// Sensor faults (FSW 3 bits 0..15).
    pub const fn sensor(&self) -> u32 {
        self.words[2] & 0xFFFF
    }

    /// BSA faults (FSW 3 bits 16..31 shifted down).
    pub const fn bsa(&self) -> u32 {
        self.words[2] >> 16
    }

    /// MCU faults (FSW 4).
    pub const fn mcu(&self) -> u32 {
        self.words[3]
    }

    /// True when a fault that stops the base is present: any critical fault, a kill switch,
    /// a commanded shutdown or disable, or an MCU that failed or requests zero speed.
    pub const fn stops_motion(&self) -> bool {
        // Per MCU n: bits 4n..4n+3 = degraded, failed, reduced performance, zero speed.
        const MCU_FAILED_OR_ZERO_SPEED: u32 = 0xAAAA;
        self.critical() != 0
            || self.has(KILL_SWITCH_ACTIVE)
            || self.has(COMMANDED_SAFETY_SHUTDOWN)
            || self.has(COMMANDED_DISABLE)
            || self.words[3] & MCU_FAILED_OR_ZERO_SPEED != 0
    }

    /// The named bits that are set.
    pub fn active(&self) -> impl Iterator<Item = &'static FaultBit> + '_ {
        NAMED_BITS.iter().filter(|b| self.has(**b))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn groups_unpack_per_reference_layout() {
        let f = FaultStatus::new([0x0008_0040, 0x0003_0010, 0x0400_0001, 0x2]);
        assert_eq!(f.architecture(), 0x40);
        assert_eq!(f.critical(), 0x80);
        assert!(f.has(VELOCITY_CONTROL_FAILED));
        assert!(f.has(KILL_SWITCH_ACTIVE));
        assert_eq!(f.communication(), 0x10);
        assert_eq!(f.internal(), 0x3);
        assert_eq!(f.sensor(), 1);
        assert_eq!(f.bsa(), 0x400);
        assert_eq!(f.mcu(), 2);
        assert!(f.stops_motion());
        let names: std::vec::Vec<_> = f.active().map(|b| b.name).collect();
        assert_eq!(
            names,
            [
                "kill switch active",
                "velocity control failed",
                "bad motion command"
            ]
        );
    }

    #[test]
    fn communication_faults_alone_do_not_stop_motion() {
        let mut f = FaultStatus::CLEAR;
        f.set(BAD_MOTION_COMMAND);
        assert!(!f.stops_motion());
        f.set(KILL_SWITCH_ACTIVE);
        assert!(f.stops_motion());
        f.clear(KILL_SWITCH_ACTIVE);
        assert!(!f.stops_motion());
        // MCU 1 requests zero speed (bit 4*1 + 3).
        assert!(FaultStatus::new([0, 0, 0, 1 << 7]).stops_motion());
        // MCU 0 merely degraded.
        assert!(!FaultStatus::new([0, 0, 0, 1]).stops_motion());
    }
}

//! RMP v3 feedback: the 32-bit items selected by the user feedback bitmaps, sent from 0x502
//! upward, two big-endian words per frame (reference §2.4).
//!
//! Item `b` of bitmap `m` (0-based) is [`FeedbackItem`] number `32 * m + b`; the items present
//! appear in that order, frame `0x502 + k` carrying items `2k` and `2k + 1` of the set. The
//! factory default ([`FeedbackBitmaps::DEFAULT`]: bitmaps 1..3 all ones, bitmap 4 zero) gives
//! 96 items in 48 frames, 0x502..=0x531, the configuration `rmp.dbc` describes. When the item
//! count is odd the last frame is padded with a zero word (no source shows what the firmware
//! does; the assembler accepts both DLC 4 and DLC 8 there).

use core::fmt;

use crate::RawFrame;
use crate::faults::FaultStatus;
use crate::frame::{be_word, be_words};
use crate::v3::OperationalState;

/// Id of the first feedback frame.
pub const FIRST_ID: u16 = 0x502;
/// Most items a feedback set can hold (three 32-item bitmaps; bitmap 4 has no items).
pub const MAX_ITEMS: usize = 96;
/// Most frames a feedback set can take.
pub const MAX_FRAMES: usize = MAX_ITEMS / 2;
/// Id of the last possible feedback frame.
pub const LAST_ID: u16 = FIRST_ID + MAX_FRAMES as u16 - 1;

/// How a feedback item's 32 bits are to be read.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ItemKind {
    /// IEEE-754 float32.
    F32,
    /// Unsigned integer (counts, enumerations).
    U32,
    /// A bit field (fault words, status bits, bitmaps).
    Bits,
    /// An IPv4 address, a.b.c.d = a*2^24 + b*2^16 + c*2^8 + d.
    Ip,
}

/// Name, representation and unit of one feedback item; the DBC file uses the same names.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ItemInfo {
    /// The item.
    pub item: FeedbackItem,
    /// Signal name (as in `rmp.dbc` and the Segway OCU demo, lower case).
    pub name: &'static str,
    /// How to read the word.
    pub kind: ItemKind,
    /// Physical unit, empty where none.
    pub unit: &'static str,
}

macro_rules! feedback_items {
    ($($variant:ident = $index:literal, $name:literal, $kind:ident, $unit:literal;)*) => {
        /// One feedback item; the discriminant is its global bit number (32 * bitmap + bit).
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
        #[repr(u8)]
        pub enum FeedbackItem {
            $(
                #[doc = concat!("`", $name, "` [", $unit, "]")]
                $variant = $index,
            )*
        }

        /// Every item in bit order: `ITEMS[i].item as usize == i`.
        pub const ITEMS: [ItemInfo; MAX_ITEMS] = [
            $(ItemInfo { item: FeedbackItem::$variant, name: $name, kind: ItemKind::$kind, unit: $unit },)*
        ];
    };
}

feedback_items! {
    FaultStatusWord1 = 0, "fault_status_word_1", Bits, "";
    FaultStatusWord2 = 1, "fault_status_word_2", Bits, "";
    FaultStatusWord3 = 2, "fault_status_word_3", Bits, "";
    FaultStatusWord4 = 3, "fault_status_word_4", Bits, "";
    Mcu0FaultStatus = 4, "mcu_0_fault_status", Bits, "";
    Mcu1FaultStatus = 5, "mcu_1_fault_status", Bits, "";
    Mcu2FaultStatus = 6, "mcu_2_fault_status", Bits, "";
    Mcu3FaultStatus = 7, "mcu_3_fault_status", Bits, "";
    OperationalTime = 8, "frame_count", F32, "s";
    OperationalState = 9, "operational_state", U32, "";
    DynamicResponse = 10, "dynamic_response", Bits, "";
    MinPropulsionBattSoc = 11, "min_propulsion_batt_soc", F32, "%";
    AuxBattSoc = 12, "aux_batt_soc", F32, "%";
    InertialXAcc = 13, "inertial_x_acc_g", F32, "g";
    InertialYAcc = 14, "inertial_y_acc_g", F32, "g";
    InertialXRate = 15, "inertial_x_rate_rps", F32, "rad/s";
    InertialYRate = 16, "inertial_y_rate_rps", F32, "rad/s";
    InertialZRate = 17, "inertial_z_rate_rps", F32, "rad/s";
    PsePitch = 18, "pse_pitch_deg", F32, "deg";
    PsePitchRate = 19, "pse_pitch_rate_dps", F32, "deg/s";
    PseRoll = 20, "pse_roll_deg", F32, "deg";
    PseRollRate = 21, "pse_roll_rate_dps", F32, "deg/s";
    PseYawRate = 22, "pse_yaw_rate_dps", F32, "deg/s";
    PseDataIsValid = 23, "pse_data_is_valid", Bits, "";
    YawRateLimit = 24, "yaw_rate_limit_rps", F32, "rad/s";
    VelocityLimit = 25, "vel_limit_mps", F32, "m/s";
    LinearAccel = 26, "linear_accel_mps2", F32, "m/s^2";
    LinearVelocity = 27, "linear_vel_mps", F32, "m/s";
    DifferentialWheelVelocity = 28, "differential_wheel_vel_rps", F32, "rad/s";
    RightFrontVelocity = 29, "right_front_vel_mps", F32, "m/s";
    LeftFrontVelocity = 30, "left_front_vel_mps", F32, "m/s";
    RightRearVelocity = 31, "right_rear_vel_mps", F32, "m/s";
    LeftRearVelocity = 32, "left_rear_vel_mps", F32, "m/s";
    RightFrontPosition = 33, "right_front_pos_m", F32, "m";
    LeftFrontPosition = 34, "left_front_pos_m", F32, "m";
    RightRearPosition = 35, "right_rear_pos_m", F32, "m";
    LeftRearPosition = 36, "left_rear_pos_m", F32, "m";
    LinearPosition = 37, "linear_pos_m", F32, "m";
    RightFrontCurrent = 38, "right_front_current_a0pk", F32, "A";
    LeftFrontCurrent = 39, "left_front_current_a0pk", F32, "A";
    RightRearCurrent = 40, "right_rear_current_a0pk", F32, "A";
    LeftRearCurrent = 41, "left_rear_current_a0pk", F32, "A";
    MaxMotorCurrent = 42, "max_motor_current_a0pk", F32, "A";
    RightFrontCurrentLimit = 43, "right_front_current_limit_a0pk", F32, "A";
    LeftFrontCurrentLimit = 44, "left_front_current_limit_a0pk", F32, "A";
    RightRearCurrentLimit = 45, "right_rear_current_limit_a0pk", F32, "A";
    LeftRearCurrentLimit = 46, "left_rear_current_limit_a0pk", F32, "A";
    MinMotorCurrentLimit = 47, "min_motor_current_limit_a0pk", F32, "A";
    FrontBaseBatt1Soc = 48, "front_base_batt_1_soc", F32, "%";
    FrontBaseBatt2Soc = 49, "front_base_batt_2_soc", F32, "%";
    RearBaseBatt1Soc = 50, "rear_base_batt_1_soc", F32, "%";
    RearBaseBatt2Soc = 51, "rear_base_batt_2_soc", F32, "%";
    FrontBaseBatt1Temp = 52, "front_base_batt_1_temp_degc", F32, "degC";
    FrontBaseBatt2Temp = 53, "front_base_batt_2_temp_degc", F32, "degC";
    RearBaseBatt1Temp = 54, "rear_base_batt_1_temp_degc", F32, "degC";
    RearBaseBatt2Temp = 55, "rear_base_batt_2_temp_degc", F32, "degC";
    VelocityTarget = 56, "vel_target_mps", F32, "m/s";
    YawRateTarget = 57, "yaw_rate_target_rps", F32, "rad/s";
    AngleTarget = 58, "angle_target_deg", F32, "deg";
    AuxBattVoltage = 59, "aux_batt_voltage_v", F32, "V";
    AuxBattCurrent = 60, "aux_batt_current_a", F32, "A";
    AuxBattTemp = 61, "aux_batt_temp_degc", F32, "degC";
    AbbSystemStatus = 62, "abb_system_status", Bits, "";
    AuxBattStatus = 63, "aux_batt_status", Bits, "";
    AuxBattFaults = 64, "aux_batt_faults", Bits, "";
    SevenP2VBattVoltage = 65, "batt_7p2v_voltage", F32, "V";
    SpSwBuildId = 66, "sp_sw_build_id", U32, "";
    UipSwBuildId = 67, "uip_sw_build_id", U32, "";
    Mcu0InstPower = 68, "mcu_0_inst_power_w", F32, "W";
    Mcu1InstPower = 69, "mcu_1_inst_power_w", F32, "W";
    Mcu2InstPower = 70, "mcu_2_inst_power_w", F32, "W";
    Mcu3InstPower = 71, "mcu_3_inst_power_w", F32, "W";
    Mcu0TotalEnergy = 72, "mcu_0_total_energy_wh", F32, "Wh";
    Mcu1TotalEnergy = 73, "mcu_1_total_energy_wh", F32, "Wh";
    Mcu2TotalEnergy = 74, "mcu_2_total_energy_wh", F32, "Wh";
    Mcu3TotalEnergy = 75, "mcu_3_total_energy_wh", F32, "Wh";
    FramVelocityLimit = 76, "fram_vel_limit_mps", F32, "m/s";
    FramAccelLimit = 77, "fram_accel_limit_mps2", F32, "m/s^2";
    FramDecelLimit = 78, "fram_decel_limit_mps2", F32, "m/s^2";
    FramDtzDecelLimit = 79, "fram_dtz_decel_limit_mps2", F32, "m/s^2";
    FramCoastDownAccel = 80, "fram_coastdown_accel_mps2", F32, "m/s^2";
    FramYawRateLimit = 81, "fram_yaw_rate_limit_rps", F32, "rad/s";
    FramYawAccelLimit = 82, "fram_yaw_accel_limit_rps2", F32, "rad/s^2";
    FramTireDiameter = 83, "fram_tire_diameter_m", F32, "m";
    FramWheelBase = 84, "fram_wheelbase_length_m", F32, "m";
    FramTrackWidth = 85, "fram_wheel_track_width_m", F32, "m";
    FramTransmissionRatio = 86, "fram_transmission_ratio", F32, "";
    FramConfigBitmap = 87, "fram_config_bitmap", Bits, "";
    FramEthIp = 88, "fram_eth_ip_address", Ip, "";
    FramEthPort = 89, "fram_eth_port_number", U32, "";
    FramEthSubnet = 90, "fram_eth_subnet_mask", Ip, "";
    FramEthGateway = 91, "fram_eth_gateway", Ip, "";
    UserFeedbackBitmap1 = 92, "user_feedback_bitmap_1", Bits, "";
    UserFeedbackBitmap2 = 93, "user_feedback_bitmap_2", Bits, "";
    UserFeedbackBitmap3 = 94, "user_feedback_bitmap_3", Bits, "";
    UserFeedbackBitmap4 = 95, "user_feedback_bitmap_4", Bits, "";
}

impl FeedbackItem {
    /// The item with global bit number `index` (0..96).
    pub fn from_index(index: usize) -> Option<Self> {
        ITEMS.get(index).map(|info| info.item)
    }

    /// Name, kind and unit.
    pub fn info(self) -> &'static ItemInfo {
        &ITEMS[self as usize]
    }

    /// First item of the forced configuration feedback (config command 30): the 20 NVM
    /// parameters in parameter-id order are exactly items 76..=95.
    pub const FORCED_CONFIG_FIRST: FeedbackItem = FeedbackItem::FramVelocityLimit;
}

/// Why a feedback layout or a feedback frame sequence was rejected.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum FeedbackError {
    /// A bitmap selects bits that name no item (bitmap 4 has none).
    InvalidBitmap {
        /// 0-based bitmap number.
        index: u8,
        /// The offending bits.
        invalid_bits: u32,
    },
    /// The id is outside 0x502..=0x531.
    NotFeedback {
        /// The id.
        id: u16,
    },
    /// A frame beyond the last one the current layout produces.
    BeyondLayout {
        /// The id.
        id: u16,
        /// Frames per set in the current layout.
        frames_per_set: usize,
    },
    /// A frame of a new set arrived (an id the current set already has, with other data)
    /// before the current set was complete: a frame of it was lost. The partial set was
    /// dropped and the new frame kept. (Frames of one set may arrive in any order, and an
    /// exact repeat of a frame is ignored.)
    Truncated {
        /// Frames of the old set that had arrived.
        received_frames: usize,
        /// Frames the set should have had.
        frames_per_set: usize,
    },
    /// A frame with the wrong data length.
    BadLength {
        /// The id.
        id: u16,
        /// Its data length.
        len: usize,
    },
}

impl fmt::Display for FeedbackError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            FeedbackError::InvalidBitmap {
                index,
                invalid_bits,
            } => write!(
                f,
                "feedback bitmap {} selects undefined items {invalid_bits:#010x}",
                index + 1
            ),
            FeedbackError::NotFeedback { id } => write!(f, "frame {id:#05x} is not feedback"),
            FeedbackError::BeyondLayout { id, frames_per_set } => write!(
                f,
                "feedback frame {id:#05x} beyond the {frames_per_set} frames of the layout"
            ),
            FeedbackError::Truncated {
                received_frames,
                frames_per_set,
            } => write!(
                f,
                "feedback set cut short after {received_frames} of {frames_per_set} frames"
            ),
            FeedbackError::BadLength { id, len } => {
                write!(f, "feedback frame {id:#05x} has {len} data bytes")
            }
        }
    }
}

impl core::error::Error for FeedbackError {}

/// The four user feedback bitmaps (config commands 17..20 on the 2014 numbering).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct FeedbackBitmaps([u32; 4]);

impl Default for FeedbackBitmaps {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Bits that name an item, per bitmap.
const VALID_BITS: [u32; 4] = [u32::MAX, u32::MAX, u32::MAX, 0];

impl FeedbackBitmaps {
    /// Factory default: every item of bitmaps 1..3 (96 items, 48 frames).
    pub const DEFAULT: Self = Self([u32::MAX, u32::MAX, u32::MAX, 0]);

    /// Validates bitmaps 1..4.
    pub fn new(bitmaps: [u32; 4]) -> Result<Self, FeedbackError> {
        for (index, (bits, valid)) in bitmaps.iter().zip(VALID_BITS).enumerate() {
            if bits & !valid != 0 {
                return Err(FeedbackError::InvalidBitmap {
                    index: index as u8,
                    invalid_bits: bits & !valid,
                });
            }
        }
        Ok(Self(bitmaps))
    }

    /// Exactly the listed items.
    pub fn from_items(items: &[FeedbackItem]) -> Self {
        let mut bitmaps = [0u32; 4];
        for item in items {
            let i = *item as usize;
            bitmaps[i / 32] |= 1 << (i % 32);
        }
        Self(bitmaps)
    }

    /// The raw words.
    pub const fn words(&self) -> [u32; 4] {
        self.0
    }

    /// True when `item` is selected.
    pub fn contains(&self, item: FeedbackItem) -> bool {
        let i = item as usize;
        self.0[i / 32] & (1 << (i % 32)) != 0
    }

    /// Number of selected items.
    pub fn item_count(&self) -> usize {
        self.0.iter().map(|w| w.count_ones() as usize).sum()
    }

    /// Position of `item` in the feedback set, if selected.
    pub fn position(&self, item: FeedbackItem) -> Option<usize> {
        if !self.contains(item) {
            return None;
        }
        let i = item as usize;
        let full: usize = self.0[..i / 32]
            .iter()
            .map(|w| w.count_ones() as usize)
            .sum();
        let below = self.0[i / 32] & ((1u32 << (i % 32)) - 1);
        Some(full + below.count_ones() as usize)
    }

    /// The selected items in set order.
    pub fn items(&self) -> impl Iterator<Item = FeedbackItem> + '_ {
        ITEMS
            .iter()
            .map(|info| info.item)
            .filter(|item| self.contains(*item))
    }
}

/// What a feedback set contains: the user items, or the NVM configuration (command 30 on).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FeedbackLayout {
    /// Items selected by the user feedback bitmaps.
    User(FeedbackBitmaps),
    /// The 20 NVM parameters in parameter-id order (items 76..=95).
    ForcedConfig,
}

const FORCED_FIRST: usize = FeedbackItem::FORCED_CONFIG_FIRST as usize;
const FORCED_COUNT: usize = 20;

impl Default for FeedbackLayout {
    fn default() -> Self {
        Self::User(FeedbackBitmaps::DEFAULT)
    }
}

impl FeedbackLayout {
    /// Items per set.
    pub fn item_count(&self) -> usize {
        match self {
            Self::User(b) => b.item_count(),
            Self::ForcedConfig => FORCED_COUNT,
        }
    }

    /// Frames per set: ceil(items / 2).
    pub fn frame_count(&self) -> usize {
        self.item_count().div_ceil(2)
    }

    /// Position of `item` in a set, if present.
    pub fn position(&self, item: FeedbackItem) -> Option<usize> {
        match self {
            Self::User(b) => b.position(item),
            Self::ForcedConfig => (item as usize)
                .checked_sub(FORCED_FIRST)
                .filter(|p| *p < FORCED_COUNT),
        }
    }

    /// The items in set order.
    pub fn items(&self) -> impl Iterator<Item = FeedbackItem> + '_ {
        let bitmaps = match self {
            Self::User(b) => *b,
            Self::ForcedConfig => FeedbackBitmaps([0, 0, 0xFFFF_F000, 0]),
        };
        ITEMS
            .iter()
            .map(|info| info.item)
            .filter(move |item| bitmaps.contains(*item))
    }
}

/// One complete feedback set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeedbackSet {
    layout: FeedbackLayout,
    words: [u32; MAX_ITEMS],
}

impl FeedbackSet {
    /// A set from words in set order (the base side); missing words read as zero.
    pub fn from_words(layout: FeedbackLayout, words_in_order: &[u32]) -> Self {
        let mut words = [0u32; MAX_ITEMS];
        let n = words_in_order.len().min(layout.item_count());
        words[..n].copy_from_slice(&words_in_order[..n]);
        Self { layout, words }
    }

    /// A set filled by asking `value_of` for each item of the layout (the base side).
    pub fn from_fn(layout: FeedbackLayout, mut value_of: impl FnMut(FeedbackItem) -> u32) -> Self {
        let mut words = [0u32; MAX_ITEMS];
        for (slot, item) in words.iter_mut().zip(layout.items()) {
            *slot = value_of(item);
        }
        Self { layout, words }
    }

    /// The layout the set was read with.
    pub const fn layout(&self) -> &FeedbackLayout {
        &self.layout
    }

    /// The words in set order.
    pub fn words(&self) -> &[u32] {
        &self.words[..self.layout.item_count()]
    }

    /// The raw word of `item`, if the layout carries it.
    pub fn get(&self, item: FeedbackItem) -> Option<u32> {
        self.layout.position(item).map(|p| self.words[p])
    }

    /// `item` read as float32 (whatever its kind), if present.
    pub fn get_f32(&self, item: FeedbackItem) -> Option<f32> {
        self.get(item).map(f32::from_bits)
    }

    /// The operational state, if present.
    pub fn operational_state(&self) -> Option<OperationalState> {
        self.get(FeedbackItem::OperationalState)
            .map(OperationalState::from_word)
    }

    /// Fault status words 1..4, if all four are present.
    pub fn fault_status(&self) -> Option<FaultStatus> {
        Some(FaultStatus::new([
            self.get(FeedbackItem::FaultStatusWord1)?,
            self.get(FeedbackItem::FaultStatusWord2)?,
            self.get(FeedbackItem::FaultStatusWord3)?,
            self.get(FeedbackItem::FaultStatusWord4)?,
        ]))
    }

    /// The CAN frames of this set, 0x502 upward.
    pub fn frames(&self) -> impl Iterator<Item = RawFrame> + '_ {
        let n = self.layout.item_count();
        (0..self.layout.frame_count()).map(move |k| {
            let first = self.words[2 * k];
            // Odd count: pad the last frame with a zero word (documented choice).
            let second = if 2 * k + 1 < n {
                self.words[2 * k + 1]
            } else {
                0
            };
            RawFrame::full(FIRST_ID + k as u16, be_words(first, second))
        })
    }
}

/// True for ids in the feedback range 0x502..=0x531.
pub const fn is_feedback_id(id: u16) -> bool {
    id >= FIRST_ID && id <= LAST_ID
}

/// Collects feedback frames into sets; one frame at a time, no allocation.
#[derive(Debug, Clone)]
pub struct FeedbackAssembler {
    layout: FeedbackLayout,
    words: [u32; MAX_ITEMS],
    /// Frames of the current set received so far (bit k: frame 0x502 + k).
    received: u64,
}

impl FeedbackAssembler {
    /// An assembler expecting `layout`.
    pub fn new(layout: FeedbackLayout) -> Self {
        Self {
            layout,
            words: [0; MAX_ITEMS],
            received: 0,
        }
    }

    /// The layout expected now.
    pub const fn layout(&self) -> &FeedbackLayout {
        &self.layout
    }

    /// Switches layout (after configuring bitmaps or forced feedback); drops a partial set.
    pub fn set_layout(&mut self, layout: FeedbackLayout) {
        self.layout = layout;
        self.received = 0;
    }

    /// Drops a partial set.
    pub fn reset(&mut self) {
        self.received = 0;
    }

    /// Feeds one frame; returns the set when its last frame arrives.
    pub fn push(&mut self, frame: &RawFrame) -> Result<Option<FeedbackSet>, FeedbackError> {
        let id = frame.id();
        if !is_feedback_id(id) {
            return Err(FeedbackError::NotFeedback { id });
        }
        let index = (id - FIRST_ID) as usize;
        let frames_per_set = self.layout.frame_count();
        if index >= frames_per_set {
            self.received = 0;
            return Err(FeedbackError::BeyondLayout { id, frames_per_set });
        }
        let items = self.layout.item_count();
        let last_is_half = items % 2 == 1 && index == frames_per_set - 1;
        let len_ok = frame.len() == 8 || (last_is_half && frame.len() == 4);
        if !len_ok {
            self.received = 0;
            return Err(FeedbackError::BadLength {
                id,
                len: frame.len(),
            });
        }
        let first = be_word(frame.data(), 0);
        let second = if last_is_half {
            0
        } else {
            be_word(frame.data(), 1)
        };
        let bit = 1u64 << index;
        let mut pending = Ok(None);
        if self.received & bit != 0 {
            let same = self.words[2 * index] == first
                && (last_is_half || self.words[2 * index + 1] == second);
            if same {
                // The same frame again (a retransmission, a duplicating gateway): nothing new.
                return Ok(None);
            }
            // A frame of the next set: the current one lost a frame. Start over with this one.
            pending = Err(FeedbackError::Truncated {
                received_frames: self.received.count_ones() as usize,
                frames_per_set,
            });
            self.received = 0;
        }
        // Frames of a set may arrive in any order: each has its own id.
        self.words[2 * index] = first;
        if !last_is_half {
            self.words[2 * index + 1] = second;
        }
        self.received |= bit;
        let full = if frames_per_set >= 64 {
            u64::MAX
        } else {
            (1u64 << frames_per_set) - 1
        };
        if self.received == full {
            self.received = 0;
            let set = FeedbackSet {
                layout: self.layout,
                words: self.words,
            };
            return pending.map(|_| Some(set));
        }
        pending
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn item_table_is_indexed_by_bit_number_and_names_are_unique() {
        for (i, info) in ITEMS.iter().enumerate() {
            assert_eq!(info.item as usize, i);
            assert_eq!(FeedbackItem::from_index(i), Some(info.item));
            for other in &ITEMS[..i] {
                assert_ne!(other.name, info.name);
            }
        }
        assert_eq!(FeedbackItem::from_index(96), None);
    }

    #[test]
    fn default_layout_is_96_items_in_48_frames() {
        let layout = FeedbackLayout::default();
        assert_eq!(layout.item_count(), 96);
        assert_eq!(layout.frame_count(), 48);
        assert_eq!(LAST_ID, 0x531);
        assert_eq!(layout.position(FeedbackItem::LinearVelocity), Some(27));
        assert_eq!(layout.position(FeedbackItem::UserFeedbackBitmap4), Some(95));
    }

    #[test]
    fn positions_follow_bit_order_in_a_sparse_layout() {
        let b = FeedbackBitmaps::from_items(&[
            FeedbackItem::LinearPosition,
            FeedbackItem::FaultStatusWord1,
            FeedbackItem::OperationalState,
        ]);
        assert_eq!(b.words(), [0x201, 0x20, 0, 0]);
        assert_eq!(b.position(FeedbackItem::FaultStatusWord1), Some(0));
        assert_eq!(b.position(FeedbackItem::OperationalState), Some(1));
        assert_eq!(b.position(FeedbackItem::LinearPosition), Some(2));
        assert_eq!(b.position(FeedbackItem::LinearVelocity), None);
        let items: std::vec::Vec<_> = b.items().collect();
        assert_eq!(
            items,
            [
                FeedbackItem::FaultStatusWord1,
                FeedbackItem::OperationalState,
                FeedbackItem::LinearPosition
            ]
        );
    }

    #[test]
    fn bitmap_4_has_no_items() {
        assert_eq!(
            FeedbackBitmaps::new([0, 0, 0, 1]),
            Err(FeedbackError::InvalidBitmap {
                index: 3,
                invalid_bits: 1
            })
        );
    }

    #[test]
    fn forced_config_layout_is_the_nvm_items() {
        let l = FeedbackLayout::ForcedConfig;
        assert_eq!(l.item_count(), 20);
        assert_eq!(l.position(FeedbackItem::FramVelocityLimit), Some(0));
        assert_eq!(l.position(FeedbackItem::UserFeedbackBitmap1), Some(16));
        assert_eq!(l.position(FeedbackItem::LinearVelocity), None);
        let items: std::vec::Vec<_> = l.items().collect();
        assert_eq!(items.len(), 20);
        assert_eq!(items[0], FeedbackItem::FramVelocityLimit);
    }

    #[test]
    fn frames_round_trip_through_the_assembler_with_odd_padding() {
        let layout = FeedbackLayout::User(FeedbackBitmaps::from_items(&[
            FeedbackItem::OperationalState,
            FeedbackItem::LinearVelocity,
            FeedbackItem::LinearPosition,
        ]));
        let set = FeedbackSet::from_fn(layout, |item| item as u32 * 3);
        let frames: std::vec::Vec<_> = set.frames().collect();
        assert_eq!(frames.len(), 2);
        assert_eq!(frames[1].data()[4..], [0, 0, 0, 0]);
        let mut asm = FeedbackAssembler::new(layout);
        assert_eq!(asm.push(&frames[0]), Ok(None));
        let got = asm.push(&frames[1]).unwrap().unwrap();
        assert_eq!(got, set);
        assert_eq!(got.get(FeedbackItem::LinearPosition), Some(37 * 3));
        // A short (DLC 4) last frame is accepted too.
        let short = RawFrame::new(0x503, &frames[1].data()[..4]).unwrap();
        asm.push(&frames[0]).unwrap();
        assert_eq!(asm.push(&short).unwrap(), Some(set));
    }

    #[test]
    fn sequence_errors_are_reported_and_recovered_from() {
        let layout = FeedbackLayout::default();
        let set = FeedbackSet::from_fn(layout, |item| item as u32);
        let frames: std::vec::Vec<_> = set.frames().collect();
        let next = FeedbackSet::from_fn(layout, |item| item as u32 + 1000);
        let next_frames: std::vec::Vec<_> = next.frames().collect();
        let mut asm = FeedbackAssembler::new(layout);
        // Out of order within a set, and repeated frames: the set is still whole and right.
        let mut order: std::vec::Vec<usize> = (0..frames.len()).rev().collect();
        order.insert(3, order[2]);
        let mut last = None;
        for &k in &order {
            last = asm.push(&frames[k]).unwrap();
        }
        assert_eq!(last, Some(set));
        // A frame of the set lost: the next set's first frame (other data) says so.
        asm.push(&frames[0]).unwrap();
        asm.push(&frames[1]).unwrap();
        assert_eq!(
            asm.push(&next_frames[0]),
            Err(FeedbackError::Truncated {
                received_frames: 2,
                frames_per_set: 48
            })
        );
        // The frame that cut the old set short started a new one.
        let mut last = None;
        for f in &next_frames[1..] {
            last = asm.push(f).unwrap();
        }
        assert_eq!(last, Some(next));
        let small = FeedbackLayout::User(FeedbackBitmaps::from_items(&[
            FeedbackItem::OperationalState,
        ]));
        asm.set_layout(small);
        assert_eq!(
            asm.push(&frames[1]),
            Err(FeedbackError::BeyondLayout {
                id: 0x503,
                frames_per_set: 1
            })
        );
        assert_eq!(
            asm.push(&RawFrame::new(0x500, &[0; 8]).unwrap()),
            Err(FeedbackError::NotFeedback { id: 0x500 })
        );
        assert_eq!(
            asm.push(&RawFrame::new(0x502, &[0; 3]).unwrap()),
            Err(FeedbackError::BadLength { id: 0x502, len: 3 })
        );
    }
}

//! The tray, planned: which slot each object rides in. The planner node assigns the slots of
//! every plan it publishes ([`assign_slots`], from the tray the executive's request describes);
//! the executive loads, asks the station and unloads by them, and admits a plan only if they
//! agree with what it believes is on the tray ([`check_slots`]). One accounting, in the plan.
//!
//! In a plan's steps (`TaskStep::tray_slot`): an unload names the slot its object is taken from;
//! a load is a bit mask of the slots it fills: its objects not yet on board, in index order, go
//! into the set bits, lowest first. Slots are taken lowest free first, objects in index order
//! (the order the loading station has always filled them).

use grop_ipc::{MAX_TRAY_SLOTS, TaskStep, TaskStepKind};

/// The tray: per slot, the object in it.
pub type Tray = [Option<u32>; MAX_TRAY_SLOTS];

/// Why a plan's tray does not add up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum TrayPlanError {
    /// A load finds no free slot for an object.
    #[error("step {step}: no free tray slot for object {object} (a tray of {slots})")]
    NoFreeSlot {
        /// The load step.
        step: usize,
        /// The object.
        object: u32,
        /// Usable slots.
        slots: usize,
    },
    /// An unload's object is not on the tray then (or not in the slot the step names).
    #[error("step {step}: object {object} is not in tray slot {slot} then")]
    NotInSlot {
        /// The unload step.
        step: usize,
        /// The object.
        object: u32,
        /// The slot the step names (its own, or the one the object would need).
        slot: u32,
    },
    /// A load's slot mask does not give each of its objects a free usable slot.
    #[error("step {step}: the load's slots {mask:#x} do not fit its objects on a tray of {slots}")]
    BadLoadSlots {
        /// The load step.
        step: usize,
        /// The step's slot mask.
        mask: u32,
        /// Usable slots.
        slots: usize,
    },
}

/// The tray a request describes (`ReplanRequestMsg::tray`: object plus one per slot).
pub fn tray_of(wire: &[u8; MAX_TRAY_SLOTS]) -> Tray {
    wire.map(|o| o.checked_sub(1).map(u32::from))
}

/// A tray on the wire (object plus one per slot, 0 empty).
pub fn tray_to_wire(tray: &Tray) -> [u8; MAX_TRAY_SLOTS] {
    tray.map(|o| o.and_then(|o| u8::try_from(o + 1).ok()).unwrap_or(0))
}

/// The objects of a load, each with the slot it goes into: the objects of `load_mask` not on
/// `tray`, in index order, paired with the set bits of `slot_mask`, lowest first. `None` when
/// they do not pair up (a count differs).
pub fn load_pairs(
    load_mask: u64,
    slot_mask: u32,
    tray: &Tray,
) -> Option<heapless::Vec<(u32, usize), MAX_TRAY_SLOTS>> {
    let mut pairs = heapless::Vec::new();
    let mut slots = (0..MAX_TRAY_SLOTS).filter(|k| slot_mask & (1 << k) != 0);
    for object in (0..64u32).filter(|o| load_mask & (1u64 << o) != 0) {
        if tray.contains(&Some(object)) {
            continue;
        }
        pairs.push((object, slots.next()?)).ok()?;
    }
    slots.next().is_none().then_some(pairs)
}

/// Assigns the slots of a plan's loads and unloads (see the module docs), from `tray` and with
/// the first `usable` slots.
pub fn assign_slots(
    steps: &mut [TaskStep],
    tray: &Tray,
    usable: usize,
) -> Result<(), TrayPlanError> {
    let usable = usable.min(MAX_TRAY_SLOTS);
    let mut tray = *tray;
    for (i, step) in steps.iter_mut().enumerate() {
        match step.kind() {
            Ok(TaskStepKind::Load) => {
                let mut mask = 0u32;
                for object in (0..64u32).filter(|o| step.load_mask & (1u64 << o) != 0) {
                    if tray.contains(&Some(object)) {
                        continue;
                    }
                    let slot = (0..usable).find(|k| tray[*k].is_none()).ok_or(
                        TrayPlanError::NoFreeSlot {
                            step: i,
                            object,
                            slots: usable,
                        },
                    )?;
                    tray[slot] = Some(object);
                    mask |= 1 << slot;
                }
                step.tray_slot = mask;
            }
            Ok(TaskStepKind::Unload) => {
                let object = step.object_index;
                let slot = tray.iter().position(|o| *o == Some(object)).ok_or(
                    TrayPlanError::NotInSlot {
                        step: i,
                        object,
                        slot: u32::MAX,
                    },
                )?;
                tray[slot] = None;
                step.tray_slot = slot as u32;
            }
            _ => step.tray_slot = 0,
        }
    }
    Ok(())
}

/// Whether a plan's slots add up from `tray` with the first `usable` slots: every load fills
/// free usable slots with exactly its objects not on board, every unload's object is in the
/// slot it names. The executive's admission of a plan: it checks, it does not re-plan.
pub fn check_slots(steps: &[TaskStep], tray: &Tray, usable: usize) -> Result<(), TrayPlanError> {
    let usable = usable.min(MAX_TRAY_SLOTS);
    let mut tray = *tray;
    for (i, step) in steps.iter().enumerate() {
        match step.kind() {
            Ok(TaskStepKind::Load) => {
                let bad = TrayPlanError::BadLoadSlots {
                    step: i,
                    mask: step.tray_slot,
                    slots: usable,
                };
                let pairs = load_pairs(step.load_mask, step.tray_slot, &tray).ok_or(bad)?;
                for (object, slot) in pairs {
                    if slot >= usable || tray[slot].is_some() {
                        return Err(bad);
                    }
                    tray[slot] = Some(object);
                }
            }
            Ok(TaskStepKind::Unload) => {
                let object = step.object_index;
                let slot = step.tray_slot as usize;
                if slot >= usable || tray[slot] != Some(object) {
                    return Err(TrayPlanError::NotInSlot {
                        step: i,
                        object,
                        slot: step.tray_slot,
                    });
                }
                tray[slot] = None;
            }
            _ => {}
        }
    }
    Ok(())
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message
mod tests {
    use super::*;
    use grop_ipc::TableSide;

    fn unload(object: u32) -> TaskStep {
        TaskStep::unload(
            object,
            TableSide::Near,
            [0.0, 6.0, 0.8],
            [0.0, 5.2, 1.57],
            0.8,
        )
    }

    #[test]
    fn loads_fill_the_lowest_free_slots_in_object_order_and_unloads_name_theirs() {
        // Object 4 already rides in slot 0; slot 2 holds object 6, which this plan leaves.
        let mut tray: Tray = [None; MAX_TRAY_SLOTS];
        tray[0] = Some(4);
        tray[2] = Some(6);
        let mut steps = vec![
            TaskStep::load(0b1011, 0.0, 1.0),
            unload(3),
            unload(4),
            unload(0),
            TaskStep::load(0b0100, 0.0, 1.0),
            unload(2),
            unload(1),
        ];
        // Objects 0, 1, 3 and the free slots 1 and 3 only: no room for the third.
        assert_eq!(
            assign_slots(&mut steps.clone(), &tray, 4),
            Err(TrayPlanError::NoFreeSlot {
                step: 0,
                object: 3,
                slots: 4
            })
        );
        tray[2] = None;
        assign_slots(&mut steps, &tray, 4).unwrap();
        assert_eq!(
            steps[0].tray_slot, 0b1110,
            "slots 1, 2, 3 for objects 0, 1, 3"
        );
        assert_eq!(
            [steps[1].tray_slot, steps[2].tray_slot, steps[3].tray_slot],
            [3, 0, 1]
        );
        assert_eq!(
            steps[4].tray_slot, 0b0001,
            "object 2 into the first free: 0"
        );
        assert_eq!([steps[5].tray_slot, steps[6].tray_slot], [0, 2]);
        check_slots(&steps, &tray, 4).unwrap();
        // What the executive checks: a slot that is taken, or a slot past the tray.
        let mut wrong = steps.clone();
        wrong[2].tray_slot = 1;
        assert_eq!(
            check_slots(&wrong, &tray, 4),
            Err(TrayPlanError::NotInSlot {
                step: 2,
                object: 4,
                slot: 1
            })
        );
        let mut wrong = steps.clone();
        wrong[0].tray_slot = 0b0111;
        assert!(matches!(
            check_slots(&wrong, &tray, 4),
            Err(TrayPlanError::BadLoadSlots { step: 0, .. })
        ));
        assert!(matches!(
            check_slots(&steps, &tray, 3),
            Err(TrayPlanError::BadLoadSlots { step: 0, .. })
        ));
        // An unload of an object that never came on board.
        let mut steps = vec![unload(5)];
        assert!(matches!(
            assign_slots(&mut steps, &tray, 4),
            Err(TrayPlanError::NotInSlot {
                step: 0,
                object: 5,
                ..
            })
        ));
    }

    #[test]
    fn the_wire_form_and_the_load_pairs() {
        let mut tray: Tray = [None; MAX_TRAY_SLOTS];
        tray[1] = Some(0);
        tray[5] = Some(63);
        let wire = tray_to_wire(&tray);
        assert_eq!(wire, [0, 1, 0, 0, 0, 64, 0, 0]);
        assert_eq!(tray_of(&wire), tray);
        let pairs = load_pairs(0b1101, 0b1001, &tray).unwrap();
        assert_eq!(
            pairs.as_slice(),
            &[(2, 0), (3, 3)],
            "object 0 is on board already"
        );
        assert!(
            load_pairs(0b1101, 0b0001, &tray).is_none(),
            "two objects, one slot"
        );
        assert!(
            load_pairs(0b0100, 0b0011, &tray).is_none(),
            "one object, two slots"
        );
    }
}

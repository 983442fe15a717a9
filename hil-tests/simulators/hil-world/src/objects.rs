//! The objects: at the loading station, on the base's tray, held by the gripper, released, and
//! judged against their targets.
//!
//! Loading: while the base stands at the loading station, people put the objects the executive
//! asks for (`load/request`, once per request) on the tray, slot by slot (the same slot order
//! the executive assumes). Holding:
//! the gripper closes on an object when its fingers are around it (the tool centre point within
//! `grasp_radius_m` of the object); the object then moves with the tool. Releasing: when the
//! fingers open, the object stays where the tool centre point is. Judging: an object counts as
//! placed when released within `tolerance_m` of its target (horizontally, and vertically within
//! the same tolerance), over the banquet table. Contacts decide between three kinds of placed:
//! *placed* (no contact of the base or the arm with furniture since the base started the leg
//! that brought it there), *placed with contact* (the end state is free, base footprint and arm
//! at release, but something touched on the way: the paper's trial, which only judges the end
//! state, counts it as a success), and *placed in collision* (the base or the arm is in
//! collision at release: a failure for the paper too).

use nalgebra::{Isometry3, Point3};

/// Judging settings.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct JudgeConfig {
    /// Largest distance from the target that counts as placed, m.
    pub tolerance_m: f64,
    /// The gripper grasps an object whose centre is this close to the tool centre point, m.
    pub grasp_radius_m: f64,
    /// Object width between the fingers, m.
    pub object_width_m: f64,
}

impl Default for JudgeConfig {
    fn default() -> Self {
        Self {
            tolerance_m: 0.05,
            grasp_radius_m: 0.03,
            object_width_m: 0.06,
        }
    }
}

/// Where an object is.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "state", rename_all = "snake_case")]
pub enum ObjectState {
    /// On the loading table.
    AtStation,
    /// In a tray slot on the base.
    OnTray {
        /// Slot index.
        slot: usize,
    },
    /// In the gripper.
    Held,
    /// Released at a world position.
    Released {
        /// Where, world frame, m.
        at: [f64; 3],
        /// Distance from the target, m.
        error_m: f64,
        /// The verdict.
        verdict: Verdict,
    },
}

/// The judgement of a released object.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// On its target, no collision on the way.
    Placed,
    /// On the table but off the target.
    Misplaced,
    /// On its target with a free end state, but the base or arm touched furniture during the
    /// leg (the paper's end-state criterion counts it as placed).
    PlacedWithContact,
    /// On its target, but the base or the arm is in collision at release.
    PlacedInCollision,
    /// Not over the table (fell).
    Dropped,
}

impl Verdict {
    /// Placed by the strict criterion (no contact at all during the leg).
    pub fn placed_strictly(self) -> bool {
        self == Verdict::Placed
    }

    /// Placed by the paper's end-state criterion (the trial simulator's: the base stands free and
    /// the arm placed the object without collision).
    pub fn placed_end_state(self) -> bool {
        matches!(self, Verdict::Placed | Verdict::PlacedWithContact)
    }
}

/// One object.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TrackedObject {
    /// Index in the task.
    pub index: usize,
    /// Target, world frame, m.
    pub target: [f64; 3],
    /// Where it is.
    pub state: ObjectState,
}

/// What changed in one step (for events).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ObjectEvent {
    /// Objects put on the tray.
    Loaded {
        /// Bit mask.
        mask: u64,
    },
    /// Grasped.
    Grasped {
        /// Object.
        index: usize,
    },
    /// Released and judged.
    Judged {
        /// Object.
        index: usize,
        /// Verdict.
        verdict: Verdict,
        /// Error, m.
        error_m: f64,
    },
}

/// All objects of a task.
#[derive(Debug, Clone)]
pub struct ObjectTracker {
    judge: JudgeConfig,
    slots_base: Vec<[f64; 3]>,
    objects: Vec<TrackedObject>,
    offered: Option<usize>,
}

impl ObjectTracker {
    /// Objects at the station with their targets; `tray_slots` in the base frame.
    pub fn new(targets: &[[f64; 3]], tray_slots: &[[f64; 3]], judge: JudgeConfig) -> Self {
        Self {
            judge,
            slots_base: tray_slots.to_vec(),
            objects: targets
                .iter()
                .enumerate()
                .map(|(index, t)| TrackedObject {
                    index,
                    target: *t,
                    state: ObjectState::AtStation,
                })
                .collect(),
            offered: None,
        }
    }

    /// The objects.
    pub fn objects(&self) -> &[TrackedObject] {
        &self.objects
    }

    fn slot_taken(&self, slot: usize) -> bool {
        self.objects
            .iter()
            .any(|o| o.state == ObjectState::OnTray { slot })
    }

    /// Loads the objects of `mask` still at the station: each into the slot the request names
    /// for it (`slots`: per slot, the object plus one; the robot's display shows it), if that
    /// slot is free; the others into free slots, in index order.
    pub fn load(&mut self, mask: u64, slots: &[u8]) -> Option<ObjectEvent> {
        let mut loaded = 0u64;
        for i in 0..self.objects.len().min(64) {
            if mask & (1u64 << i) == 0 || self.objects[i].state != ObjectState::AtStation {
                continue;
            }
            let named = slots
                .iter()
                .position(|o| usize::from(*o) == i + 1)
                .filter(|s| *s < self.slots_base.len() && !self.slot_taken(*s));
            let Some(slot) =
                named.or_else(|| (0..self.slots_base.len()).find(|s| !self.slot_taken(*s)))
            else {
                break;
            };
            self.objects[i].state = ObjectState::OnTray { slot };
            loaded |= 1u64 << i;
        }
        (loaded != 0).then_some(ObjectEvent::Loaded { mask: loaded })
    }

    /// Whether any object waits at the station.
    pub fn any_at_station(&self) -> bool {
        self.objects
            .iter()
            .any(|o| o.state == ObjectState::AtStation)
    }

    /// One step of the gripper: `world_from_base` is the true base pose, `tcp` the tool centre
    /// point in the world, `opening_m` the finger gap. Returns the width of the object between
    /// the fingers, to give the simulated gripper (so it stops on it), and what happened.
    pub fn step_gripper(
        &mut self,
        world_from_base: &Isometry3<f64>,
        tcp: Point3<f64>,
        opening_m: f64,
        contact_this_leg: bool,
        end_state_collides: bool,
        table_contains: impl Fn(f64, f64) -> bool,
    ) -> (Option<f64>, Option<ObjectEvent>) {
        let w = self.judge.object_width_m;
        if let Some(held) = self
            .objects
            .iter()
            .position(|o| o.state == ObjectState::Held)
        {
            if opening_m > w + 0.005 {
                let target = self.objects[held].target;
                let at = [tcp.x, tcp.y, tcp.z];
                let horizontal = (at[0] - target[0]).hypot(at[1] - target[1]);
                let error_m = horizontal.hypot(at[2] - target[2]);
                let verdict = if !table_contains(at[0], at[1]) {
                    Verdict::Dropped
                } else if error_m > self.judge.tolerance_m {
                    Verdict::Misplaced
                } else if end_state_collides {
                    Verdict::PlacedInCollision
                } else if contact_this_leg {
                    Verdict::PlacedWithContact
                } else {
                    Verdict::Placed
                };
                self.objects[held].state = ObjectState::Released {
                    at,
                    error_m,
                    verdict,
                };
                self.offered = None;
                return (
                    None,
                    Some(ObjectEvent::Judged {
                        index: held,
                        verdict,
                        error_m,
                    }),
                );
            }
            return (Some(w), None);
        }
        // Fingers open around a tray object: offer it; closed on it: it is held.
        if let Some(i) = self.offered {
            if opening_m <= w + 0.002 {
                self.objects[i].state = ObjectState::Held;
                return (Some(w), Some(ObjectEvent::Grasped { index: i }));
            }
        }
        self.offered = self.objects.iter().position(|o| match o.state {
            ObjectState::OnTray { slot } => {
                let s = self.slots_base[slot];
                let p = world_from_base * Point3::new(s[0], s[1], s[2]);
                (p - tcp).norm() <= self.judge.grasp_radius_m
            }
            _ => false,
        });
        // Only offer an object to fingers wide enough to go around it.
        if self.offered.is_some() && opening_m < w + 0.002 {
            self.offered = None;
        }
        (self.offered.map(|_| w), None)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn load_grasp_release_and_judge() {
        let slots = [[-0.2, 0.0, 1.1]];
        let mut t = ObjectTracker::new(&[[1.0, 6.0, 1.3]], &slots, JudgeConfig::default());
        assert!(matches!(
            t.load(1, &[]),
            Some(ObjectEvent::Loaded { mask: 1 })
        ));
        assert_eq!(t.load(1, &[]), None, "nothing left at the station");
        let base = Isometry3::translation(1.0, 5.0, 0.0);
        let at_slot = Point3::new(0.8, 5.0, 1.1);
        let table = |_x: f64, y: f64| (5.8..6.2).contains(&y);
        // Open fingers at the slot: offered.
        let (width, _) = t.step_gripper(&base, at_slot, 0.14, false, false, table);
        assert_eq!(width, Some(0.06));
        // Closed on it.
        let (_, ev) = t.step_gripper(&base, at_slot, 0.06, false, false, table);
        assert_eq!(ev, Some(ObjectEvent::Grasped { index: 0 }));
        // Carried to 2 cm off the target and opened.
        let (_, ev) = t.step_gripper(&base, Point3::new(1.02, 6.0, 1.3), 0.1, false, false, table);
        match ev {
            Some(ObjectEvent::Judged {
                verdict, error_m, ..
            }) => {
                assert_eq!(verdict, Verdict::Placed);
                assert!((error_m - 0.02).abs() < 1e-9);
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn the_station_puts_each_object_in_the_slot_the_request_names() {
        let slots = [[-0.2, 0.0, 1.1], [-0.2, 0.2, 1.1], [-0.2, 0.4, 1.1]];
        let targets = [[1.0, 6.0, 1.3], [2.0, 6.0, 1.3], [3.0, 6.0, 1.3]];
        let mut t = ObjectTracker::new(&targets, &slots, JudgeConfig::default());
        // Object 0 into slot 2, object 1 into slot 0; object 2 named nowhere: the free slot.
        t.load(0b111, &[2, 0, 1]);
        let slot_of = |i: usize| match t.objects()[i].state {
            ObjectState::OnTray { slot } => slot,
            ref other => panic!("object {i}: {other:?}"),
        };
        assert_eq!([slot_of(0), slot_of(1), slot_of(2)], [2, 0, 1]);
    }

    #[test]
    fn a_collision_or_a_miss_is_not_a_placement() {
        let slots = [[-0.2, 0.0, 1.1], [-0.2, 0.2, 1.1]];
        let mut t = ObjectTracker::new(
            &[[1.0, 6.0, 1.3], [2.0, 6.0, 1.3]],
            &slots,
            JudgeConfig::default(),
        );
        t.load(3, &[]);
        let base = Isometry3::translation(1.0, 5.0, 0.0);
        let table = |_x: f64, y: f64| (5.8..6.2).contains(&y);
        let slot0 = Point3::new(0.8, 5.0, 1.1);
        t.step_gripper(&base, slot0, 0.14, false, false, table);
        t.step_gripper(&base, slot0, 0.06, false, false, table);
        let (_, ev) = t.step_gripper(&base, Point3::new(1.0, 6.0, 1.3), 0.1, true, false, table);
        assert!(matches!(
            ev,
            Some(ObjectEvent::Judged {
                verdict: Verdict::PlacedWithContact,
                ..
            })
        ));
        let slot1 = Point3::new(0.8, 5.2, 1.1);
        t.step_gripper(&base, slot1, 0.14, false, false, table);
        t.step_gripper(&base, slot1, 0.06, false, false, table);
        let (_, ev) = t.step_gripper(&base, Point3::new(1.5, 6.0, 1.3), 0.1, false, false, table);
        assert!(matches!(
            ev,
            Some(ObjectEvent::Judged {
                verdict: Verdict::Misplaced,
                ..
            })
        ));
    }
}

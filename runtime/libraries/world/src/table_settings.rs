//! Whole table settings: place settings of three items (plate, glass, cutlery) in front of the
//! seats on both sides of the banquet table, one chair per seat (issue 13).
//!
//! Seats: `ceil(n/2)` on the near side and `floor(n/2)` on the far side, facing each other, spread
//! evenly over the table's length (seat `i` of a side at the centre of the `i`-th of equal slices,
//! west to east). Each seat's items, in the frame of the diner facing the table (`along` = to the
//! diner's right, `inward` = from the diner's table edge towards the centre line):
//!
//! | item | along (m) | inward (m) |
//! |---|---|---|
//! | plate | 0.00 | 0.10 |
//! | glass | +0.18 (right) | 0.16 |
//! | cutlery | -0.18 (left) | 0.08 |
//!
//! A near-side diner faces +y, so "right" is +x; a far-side diner faces -y, so "right" is -x. Every
//! item is a target at the default placing height ([`UnloadTarget::DEFAULT_Z_M`]). Object (and
//! target) index `3 * seat + item`, seats near side first (west to east), then far side (west to
//! east); items in the order of the table above.
//!
//! Chairs: one per seat, seeded: centre `0.32 + U[0, 0.55]` m from the table edge, shifted
//! along the table by `U[-0.25, 0.25]` m, yaw facing the table `+ U[-0.5, 0.5]` rad.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::generate::mix_seed;
#[cfg(doc)]
use crate::scene::DEFAULT_CHAIR_SIZE_M;
use crate::scene::{Chair, Scene, UnloadTarget};
use crate::view::Side;

/// Items of one place setting.
pub const ITEMS_PER_SETTING: usize = 3;
/// Most place settings a generated table holds (36 objects, the largest task).
pub const MAX_PLACE_SETTINGS: usize = 12;

/// An item of a place setting.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PlaceSettingItem {
    /// The plate, centred in front of the seat.
    Plate,
    /// The glass (or cup), to the diner's right and further in.
    Glass,
    /// The cutlery, to the diner's left, near the edge.
    Cutlery,
}

impl PlaceSettingItem {
    /// The items in object-index order within a setting.
    pub const ALL: [PlaceSettingItem; ITEMS_PER_SETTING] = [
        PlaceSettingItem::Plate,
        PlaceSettingItem::Glass,
        PlaceSettingItem::Cutlery,
    ];

    /// Offset from the seat (m): (to the diner's right, inward from the diner's table edge).
    pub fn offset_m(self) -> (f64, f64) {
        match self {
            PlaceSettingItem::Plate => (0.0, 0.10),
            PlaceSettingItem::Glass => (0.18, 0.16),
            PlaceSettingItem::Cutlery => (-0.18, 0.08),
        }
    }

    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            PlaceSettingItem::Plate => "plate",
            PlaceSettingItem::Glass => "glass",
            PlaceSettingItem::Cutlery => "cutlery",
        }
    }
}

/// Where one object of a table setting goes: which seat, which side, which item.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SettingObject {
    /// Seat index (near side first, west to east).
    pub seat: usize,
    /// The side of the table the seat is on.
    pub seat_side: Side,
    /// The seat's x (m).
    pub seat_x_m: f64,
    /// The item.
    pub item: PlaceSettingItem,
}

/// Least distance (m) from a chair's centre to the table edge: a [`DEFAULT_CHAIR_SIZE_M`] chair
/// turned by 0.5 rad reaches `0.5 * 0.45 * (cos 0.5 + sin 0.5) = 0.306` m.
const CHAIR_CLEARANCE_M: f64 = 0.32;

/// Why a table setting cannot be generated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum TableSettingsError {
    /// Zero place settings, or more than [`MAX_PLACE_SETTINGS`].
    #[error("{0} place settings; a table holds 1..={MAX_PLACE_SETTINGS}")]
    SettingCount(usize),
}

/// The objects of `n_settings` place settings on `scene`'s banquet table, in object-index order.
pub fn setting_objects(
    scene: &Scene,
    n_settings: usize,
) -> Result<Vec<SettingObject>, TableSettingsError> {
    if n_settings == 0 || n_settings > MAX_PLACE_SETTINGS {
        return Err(TableSettingsError::SettingCount(n_settings));
    }
    let bt = &scene.banquet_table;
    let near = n_settings.div_ceil(2);
    let mut out = Vec::with_capacity(n_settings * ITEMS_PER_SETTING);
    for (side, count) in [(Side::Near, near), (Side::Far, n_settings - near)] {
        let slice = bt.length_m() / count.max(1) as f64;
        for i in 0..count {
            let seat_x_m = bt.x_min_m() + (i as f64 + 0.5) * slice;
            let seat = out.len() / ITEMS_PER_SETTING;
            for item in PlaceSettingItem::ALL {
                out.push(SettingObject {
                    seat,
                    seat_side: side,
                    seat_x_m,
                    item,
                });
            }
        }
    }
    Ok(out)
}

impl SettingObject {
    /// The object's target on `scene`'s table.
    pub fn target(&self, scene: &Scene) -> UnloadTarget {
        let bt = &scene.banquet_table;
        let (along, inward) = self.item.offset_m();
        let (x_m, y_m) = match self.seat_side {
            Side::Near => (self.seat_x_m + along, bt.y_min_m() + inward),
            Side::Far => (self.seat_x_m - along, bt.y_max_m() - inward),
        };
        UnloadTarget {
            x_m,
            y_m,
            z_m: UnloadTarget::DEFAULT_Z_M,
        }
    }
}

/// The paper's room with `n_settings` place settings (3 items each) and a chair at every seat,
/// seeded. The scene validates (a test checks every count from 1 to [`MAX_PLACE_SETTINGS`]).
pub fn table_settings_scene(seed: u64, n_settings: usize) -> Result<Scene, TableSettingsError> {
    let mut scene = Scene::empty_paper_room();
    let objects = setting_objects(&scene, n_settings)?;
    let mut rng = ChaCha8Rng::seed_from_u64(mix_seed(seed, 0x7365_7474, n_settings as u64));
    scene.name = format!("settings-{seed}-{n_settings}");
    let bt = scene.banquet_table;
    for seat in objects.iter().step_by(ITEMS_PER_SETTING) {
        // A square chair turned by up to 0.5 rad reaches 0.5 * size * (cos 0.5 + sin 0.5) = 0.31 m
        // from its centre: at least 0.32 m out, it never touches the table.
        let pull_out = CHAIR_CLEARANCE_M + rng.random_range(0.0..0.55);
        let dx = rng.random_range(-0.25..0.25);
        let dyaw = rng.random_range(-0.5..0.5);
        let (y, yaw) = match seat.seat_side {
            Side::Near => (bt.y_min_m() - pull_out, std::f64::consts::FRAC_PI_2),
            Side::Far => (bt.y_max_m() + pull_out, -std::f64::consts::FRAC_PI_2),
        };
        scene
            .chairs
            .push(Chair::new(seat.seat_x_m + dx, y, yaw + dyaw));
    }
    scene.targets = objects.iter().map(|o| o.target(&scene)).collect();
    Ok(scene)
}

/// `count` table-setting scenes of `n_settings` place settings (seeds derived from `seed`).
pub fn table_settings_suite(
    seed: u64,
    n_settings: usize,
    count: usize,
) -> Result<Vec<Scene>, TableSettingsError> {
    (0..count as u64)
        .map(|i| table_settings_scene(mix_seed(seed, 0x7375_6974, i), n_settings))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_setting_count_gives_a_valid_scene() {
        for n in 1..=MAX_PLACE_SETTINGS {
            let scene = table_settings_scene(3, n).expect("in range");
            scene
                .validate()
                .unwrap_or_else(|e| panic!("{n} settings: {e}"));
            assert_eq!(scene.targets.len(), 3 * n);
            assert_eq!(scene.chairs.len(), n);
        }
    }

    #[test]
    fn items_sit_in_front_of_their_seat_on_its_half() {
        let scene = table_settings_scene(1, 12).expect("in range");
        let objects = setting_objects(&scene, 12).expect("in range");
        assert_eq!(
            objects.iter().filter(|o| o.seat_side == Side::Near).count(),
            18
        );
        for (o, t) in objects.iter().zip(&scene.targets) {
            assert_eq!(Side::of_y(t.y_m), o.seat_side, "{o:?} {t:?}");
            assert!((t.x_m - o.seat_x_m).abs() <= 0.18 + 1e-12);
            // Glass right of the diner: +x near, -x far.
            if o.item == PlaceSettingItem::Glass {
                let right = match o.seat_side {
                    Side::Near => t.x_m > o.seat_x_m,
                    Side::Far => t.x_m < o.seat_x_m,
                };
                assert!(right, "{o:?} {t:?}");
            }
        }
    }

    #[test]
    fn bad_counts_are_errors_and_seeds_repeat() {
        assert_eq!(
            table_settings_scene(0, 0).unwrap_err(),
            TableSettingsError::SettingCount(0)
        );
        assert!(table_settings_scene(0, 13).is_err());
        assert_eq!(
            table_settings_scene(9, 8).expect("ok"),
            table_settings_scene(9, 8).expect("ok")
        );
        assert_ne!(
            table_settings_scene(9, 8).expect("ok").chairs,
            table_settings_scene(10, 8).expect("ok").chairs
        );
    }
}

//! `base/scan`: the range sensor's revolution as the executive's collision monitor took it, for
//! the mission log and its viewers (the executive publishes it; nothing onboard reads it).

use iceoryx2::prelude::ZeroCopySend;

/// Bins of a [`ScanMsg`]: one per degree of bearing around the base.
pub const SCAN_BINS: usize = 360;

/// One revolution of the range sensor, reduced to the nearest return per degree of
/// bearing (`base/scan`): points on the floor plane in the base frame (x forward, y left),
/// metres, deskewed to the revolution's end. A bin without a return is NaN.
#[derive(Clone, Copy, Debug, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("grop_ipc::ScanMsg/v1")]
pub struct ScanMsg {
    /// Revolution counter of the publisher, increasing.
    pub seq: u64,
    /// Time of the revolution's end on the runtime clock, nanoseconds.
    pub stamp_ns: u64,
    /// Nearest return per bin, x then y (m); bin i covers bearings from -pi + i * pi / 180.
    pub points_m: [[f32; 2]; SCAN_BINS],
}

impl ScanMsg {
    /// The bin of a point's bearing.
    fn bin(x: f32, y: f32) -> usize {
        let bearing = y.atan2(x) + std::f32::consts::PI;
        ((bearing / (2.0 * std::f32::consts::PI) * SCAN_BINS as f32) as usize).min(SCAN_BINS - 1)
    }

    /// Replaces the points by the nearest of `points` per bin (non-finite points left out).
    pub fn set_points(&mut self, points: impl Iterator<Item = [f32; 2]>) {
        self.points_m = [[f32::NAN; 2]; SCAN_BINS];
        for [x, y] in points {
            if !(x.is_finite() && y.is_finite()) || (x == 0.0 && y == 0.0) {
                continue;
            }
            let slot = &mut self.points_m[Self::bin(x, y)];
            let nearer = slot[0].is_nan() || x.hypot(y) < slot[0].hypot(slot[1]);
            if nearer {
                *slot = [x, y];
            }
        }
    }

    /// The bins that hold a return.
    pub fn points(&self) -> impl Iterator<Item = [f32; 2]> + '_ {
        self.points_m.iter().copied().filter(|p| !p[0].is_nan())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_nearest_return_per_degree_is_kept() {
        let mut m = ScanMsg {
            seq: 0,
            stamp_ns: 0,
            points_m: [[0.0; 2]; SCAN_BINS],
        };
        m.set_points(
            [
                [2.0, 0.0],
                [1.0, 0.001],
                [0.0, 3.0],
                [f32::NAN, 1.0],
                [-1.0, -0.0001],
            ]
            .into_iter(),
        );
        let pts: Vec<[f32; 2]> = m.points().collect();
        assert_eq!(pts, vec![[-1.0, -0.0001], [1.0, 0.001], [0.0, 3.0]]);
    }
}

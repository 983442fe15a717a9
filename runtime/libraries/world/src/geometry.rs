//! Planar geometry of footprints: oriented rectangles seen from above.
//!
//! Everything on the floor (base, chairs, tables) is an oriented rectangle in the world's x-y
//! plane. Overlap uses the separating-axis theorem, exact for two convex rectangles.

/// An oriented rectangle in the world x-y plane (metres, yaw about +z, counter-clockwise).
///
/// `half_length_m` runs along the rectangle's own x axis (its heading), `half_width_m` along its
/// own y axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OrientedRect {
    /// Centre, world x (m).
    pub center_x_m: f64,
    /// Centre, world y (m).
    pub center_y_m: f64,
    /// Half extent along the rectangle's heading (m).
    pub half_length_m: f64,
    /// Half extent across the rectangle's heading (m).
    pub half_width_m: f64,
    cos_yaw: f64,
    sin_yaw: f64,
}

/// Penetration below this depth (m) counts as touching, not overlapping, so that furniture
/// placed edge to edge (table segments, a chair flush with a wall) is accepted.
pub const TOUCH_TOLERANCE_M: f64 = 1e-9;

impl OrientedRect {
    /// A rectangle centred at (x, y), `length_m` along its heading `yaw_rad`, `width_m` across.
    pub fn new(
        center_x_m: f64,
        center_y_m: f64,
        length_m: f64,
        width_m: f64,
        yaw_rad: f64,
    ) -> Self {
        let (sin_yaw, cos_yaw) = yaw_rad.sin_cos();
        Self {
            center_x_m,
            center_y_m,
            half_length_m: 0.5 * length_m,
            half_width_m: 0.5 * width_m,
            cos_yaw,
            sin_yaw,
        }
    }

    /// An axis-aligned rectangle from its bounds.
    pub fn from_bounds(x_min_m: f64, x_max_m: f64, y_min_m: f64, y_max_m: f64) -> Self {
        Self::new(
            0.5 * (x_min_m + x_max_m),
            0.5 * (y_min_m + y_max_m),
            x_max_m - x_min_m,
            y_max_m - y_min_m,
            0.0,
        )
    }

    /// Yaw of the rectangle's heading (rad, in (-pi, pi]).
    pub fn yaw_rad(&self) -> f64 {
        self.sin_yaw.atan2(self.cos_yaw)
    }

    /// Unit vector of the heading (local x axis) in world coordinates.
    pub fn heading(&self) -> (f64, f64) {
        (self.cos_yaw, self.sin_yaw)
    }

    /// Distance from the centre to a corner (m): the radius of the circumscribed circle.
    pub fn circumradius_m(&self) -> f64 {
        // Not `hypot`: libm's is slow and overflow is impossible at these sizes. Only the
        // overlap test's cheap rejection uses it, whose answer does not depend on the last bit.
        (self.half_length_m * self.half_length_m + self.half_width_m * self.half_width_m).sqrt()
    }

    /// The four corners, counter-clockwise, starting at the front-left.
    pub fn corners(&self) -> [(f64, f64); 4] {
        let (c, s) = (self.cos_yaw, self.sin_yaw);
        let (hl, hw) = (self.half_length_m, self.half_width_m);
        let at = |lx: f64, ly: f64| {
            (
                self.center_x_m + c * lx - s * ly,
                self.center_y_m + s * lx + c * ly,
            )
        };
        [at(hl, hw), at(-hl, hw), at(-hl, -hw), at(hl, -hw)]
    }

    /// Axis-aligned bounds `(x_min, x_max, y_min, y_max)` (m).
    pub fn bounds(&self) -> (f64, f64, f64, f64) {
        let ex = self.half_length_m * self.cos_yaw.abs() + self.half_width_m * self.sin_yaw.abs();
        let ey = self.half_length_m * self.sin_yaw.abs() + self.half_width_m * self.cos_yaw.abs();
        (
            self.center_x_m - ex,
            self.center_x_m + ex,
            self.center_y_m - ey,
            self.center_y_m + ey,
        )
    }

    /// Whether the point lies inside or on the border.
    pub fn contains_point(&self, x_m: f64, y_m: f64) -> bool {
        let (local_x, local_y) = self.local_coordinates(x_m, y_m);
        local_x.abs() <= self.half_length_m && local_y.abs() <= self.half_width_m
    }

    /// The point in the rectangle's frame: along its length and across it, from its centre (m).
    pub fn local_coordinates(&self, x_m: f64, y_m: f64) -> (f64, f64) {
        let dx = x_m - self.center_x_m;
        let dy = y_m - self.center_y_m;
        (
            self.cos_yaw * dx + self.sin_yaw * dy,
            -self.sin_yaw * dx + self.cos_yaw * dy,
        )
    }

    /// Whether the two rectangles overlap by more than [`TOUCH_TOLERANCE_M`]
    /// (separating-axis theorem over the four edge normals).
    pub fn overlaps(&self, other: &OrientedRect) -> bool {
        let tx = other.center_x_m - self.center_x_m;
        let ty = other.center_y_m - self.center_y_m;
        // Cheap rejection on the circumscribed circles first: most pairs are far apart.
        let reach = self.circumradius_m() + other.circumradius_m();
        if tx * tx + ty * ty > reach * reach {
            return false;
        }
        let axes = [
            (self.cos_yaw, self.sin_yaw),
            (-self.sin_yaw, self.cos_yaw),
            (other.cos_yaw, other.sin_yaw),
            (-other.sin_yaw, other.cos_yaw),
        ];
        axes.iter().all(|&(ax, ay)| {
            let distance = (tx * ax + ty * ay).abs();
            distance + TOUCH_TOLERANCE_M
                < self.projected_radius(ax, ay) + other.projected_radius(ax, ay)
        })
    }

    /// The gap between the two rectangles (m; 0 when they touch or overlap): the smallest
    /// distance from a corner of one to an edge of the other.
    pub fn distance_to(&self, other: &OrientedRect) -> f64 {
        if self.overlaps(other) {
            return 0.0;
        }
        let gap = |a: &OrientedRect, b: &OrientedRect| {
            let edges = b.corners();
            a.corners()
                .iter()
                .map(|&p| {
                    (0..4)
                        .map(|k| point_segment_distance(p, edges[k], edges[(k + 1) % 4]))
                        .fold(f64::INFINITY, f64::min)
                })
                .fold(f64::INFINITY, f64::min)
        };
        gap(self, other).min(gap(other, self))
    }

    /// Whether the rectangle lies completely inside the axis-aligned bounds (touching allowed).
    pub fn inside_bounds(&self, x_min_m: f64, x_max_m: f64, y_min_m: f64, y_max_m: f64) -> bool {
        let (x0, x1, y0, y1) = self.bounds();
        x0 >= x_min_m - TOUCH_TOLERANCE_M
            && x1 <= x_max_m + TOUCH_TOLERANCE_M
            && y0 >= y_min_m - TOUCH_TOLERANCE_M
            && y1 <= y_max_m + TOUCH_TOLERANCE_M
    }

    /// Half the extent of the rectangle's projection on the unit axis (ax, ay).
    fn projected_radius(&self, ax: f64, ay: f64) -> f64 {
        self.half_length_m * (self.cos_yaw * ax + self.sin_yaw * ay).abs()
            + self.half_width_m * (-self.sin_yaw * ax + self.cos_yaw * ay).abs()
    }
}

/// [`OrientedRect::overlaps`] between a fixed rectangle and one that only moves (the same size
/// and heading everywhere, as a base at one yaw): what the test computes from sizes and headings
/// alone (the reach of the circumscribed circles, the four axes and the projected radii) is done
/// once, so that each position costs a few multiplications. Answers exactly as `overlaps` (the
/// same floating-point operations on the same values, in either order of the two rectangles).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OverlapProbe {
    fixed_x_m: f64,
    fixed_y_m: f64,
    reach_sq: f64,
    axes: [(f64, f64); 4],
    radii: [f64; 4],
}

impl OverlapProbe {
    /// A probe of `fixed` against `moving` at any centre.
    pub fn new(fixed: &OrientedRect, moving: &OrientedRect) -> Self {
        let reach = fixed.circumradius_m() + moving.circumradius_m();
        let axes = [
            (fixed.cos_yaw, fixed.sin_yaw),
            (-fixed.sin_yaw, fixed.cos_yaw),
            (moving.cos_yaw, moving.sin_yaw),
            (-moving.sin_yaw, moving.cos_yaw),
        ];
        Self {
            fixed_x_m: fixed.center_x_m,
            fixed_y_m: fixed.center_y_m,
            reach_sq: reach * reach,
            axes,
            radii: axes
                .map(|(ax, ay)| fixed.projected_radius(ax, ay) + moving.projected_radius(ax, ay)),
        }
    }

    /// Whether the moving rectangle centred at (`x_m`, `y_m`) overlaps the fixed one.
    pub fn overlaps_at(&self, x_m: f64, y_m: f64) -> bool {
        let tx = x_m - self.fixed_x_m;
        let ty = y_m - self.fixed_y_m;
        if tx * tx + ty * ty > self.reach_sq {
            return false;
        }
        self.axes
            .iter()
            .zip(&self.radii)
            .all(|(&(ax, ay), &radius)| (tx * ax + ty * ay).abs() + TOUCH_TOLERANCE_M < radius)
    }
}

/// Distance from point `p` to the segment `a`-`b` (m).
pub fn point_segment_distance(p: (f64, f64), a: (f64, f64), b: (f64, f64)) -> f64 {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p.0 - a.0 - t * dx).hypot(p.1 - a.1 - t * dy)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_4;

    /// The probe answers exactly as `overlaps`, in both orders of the two rectangles, for
    /// random sizes, headings (the facing yaws among them) and positions around the fixed one,
    /// edge-to-edge contacts included.
    #[test]
    fn overlap_probe_equals_overlaps() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let (mut hits, mut misses) = (0, 0);
        for k in 0..400 {
            let yaw = |rng: &mut rand_chacha::ChaCha8Rng| match k % 3 {
                0 => [
                    0.0,
                    std::f64::consts::FRAC_PI_2,
                    -std::f64::consts::FRAC_PI_2,
                ][rng.random_range(0..3usize)],
                _ => rng.random_range(-3.2..3.2),
            };
            let (fy, my) = (yaw(&mut rng), yaw(&mut rng));
            let fixed = OrientedRect::new(
                rng.random_range(-5.0..5.0),
                rng.random_range(-5.0..5.0),
                rng.random_range(0.1..3.0),
                rng.random_range(0.1..1.0),
                fy,
            );
            let moving = OrientedRect::new(
                0.0,
                0.0,
                rng.random_range(0.2..1.0),
                rng.random_range(0.2..0.8),
                my,
            );
            let probe = OverlapProbe::new(&fixed, &moving);
            for _ in 0..100 {
                let mut at = moving;
                at.center_x_m = fixed.center_x_m + rng.random_range(-2.5..2.5);
                at.center_y_m = fixed.center_y_m + rng.random_range(-2.0..2.0);
                let expected = at.overlaps(&fixed);
                assert_eq!(expected, fixed.overlaps(&at));
                assert_eq!(probe.overlaps_at(at.center_x_m, at.center_y_m), expected);
                if expected { hits += 1 } else { misses += 1 }
            }
        }
        // Edge to edge, axis aligned: touching is not overlapping, for the probe too.
        let table = OrientedRect::from_bounds(0.0, 2.0, 0.0, 1.0);
        let base = OrientedRect::from_bounds(-0.5, 0.5, -0.25, 0.25);
        let probe = OverlapProbe::new(&table, &base);
        assert!(!probe.overlaps_at(-0.5, 0.5));
        assert!(probe.overlaps_at(-0.49, 0.5));
        assert!(
            hits > 1000 && misses > 1000,
            "{hits} overlaps, {misses} apart"
        );
    }

    #[test]
    fn axis_aligned_overlap_and_separation() {
        let a = OrientedRect::from_bounds(0.0, 1.0, 0.0, 1.0);
        assert!(a.overlaps(&OrientedRect::from_bounds(0.5, 1.5, 0.5, 1.5)));
        assert!(!a.overlaps(&OrientedRect::from_bounds(1.01, 2.0, 0.0, 1.0)));
        // Edge to edge is touching, not overlapping.
        assert!(!a.overlaps(&OrientedRect::from_bounds(1.0, 2.0, 0.0, 1.0)));
    }

    #[test]
    fn rotated_square_needs_the_diagonal() {
        // A unit square rotated 45 degrees reaches 0.707 m from its centre along x.
        let diamond = OrientedRect::new(0.0, 0.0, 1.0, 1.0, FRAC_PI_4);
        assert!(diamond.overlaps(&OrientedRect::from_bounds(0.6, 1.6, -0.05, 0.05)));
        assert!(!diamond.overlaps(&OrientedRect::from_bounds(0.72, 1.6, -0.05, 0.05)));
        // Near the diamond's corner region but outside its edge: only SAT on its own axes
        // separates these; the axis-aligned bounds would overlap.
        assert!(!diamond.overlaps(&OrientedRect::from_bounds(0.45, 0.6, 0.45, 0.6)));
    }

    #[test]
    fn contains_point_follows_yaw() {
        let r = OrientedRect::new(1.0, 2.0, 2.0, 0.2, std::f64::consts::FRAC_PI_2);
        assert!(r.contains_point(1.0, 2.9));
        assert!(!r.contains_point(1.5, 2.0));
    }

    #[test]
    fn bounds_of_rotated_rect() {
        let r = OrientedRect::new(0.0, 0.0, 2.0, 1.0, std::f64::consts::FRAC_PI_2);
        let (x0, x1, y0, y1) = r.bounds();
        assert!((x0 + 0.5).abs() < 1e-12 && (x1 - 0.5).abs() < 1e-12);
        assert!((y0 + 1.0).abs() < 1e-12 && (y1 - 1.0).abs() < 1e-12);
    }
}

#[cfg(test)]
mod distance_tests {
    use super::*;

    #[test]
    fn gaps_between_rectangles() {
        let a = OrientedRect::new(0.0, 0.0, 0.6, 0.55, 0.0);
        // 0.1 m ahead of the front edge.
        let b = OrientedRect::new(0.6, 0.0, 0.4, 0.4, 0.0);
        assert!((a.distance_to(&b) - 0.1).abs() < 1e-12);
        assert!((b.distance_to(&a) - 0.1).abs() < 1e-12);
        // Corner to corner, diagonally.
        let c = OrientedRect::new(0.3 + 0.2 + 0.03, 0.275 + 0.2 + 0.04, 0.4, 0.4, 0.0);
        assert!((a.distance_to(&c) - 0.05).abs() < 1e-9);
        // Overlapping: 0.
        let d = OrientedRect::new(0.2, 0.1, 0.4, 0.4, 0.7);
        assert_eq!(a.distance_to(&d), 0.0);
        // A turned rectangle's corner nearest an edge.
        let e = OrientedRect::new(0.6, 0.0, 0.2, 0.2, std::f64::consts::FRAC_PI_4);
        let expected = 0.6 - 0.1 * std::f64::consts::SQRT_2 - 0.3;
        assert!((a.distance_to(&e) - expected).abs() < 1e-9);
    }
}

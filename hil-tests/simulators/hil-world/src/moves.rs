//! Things move: chairs the world moves during a mission, after the overhead frame the first plan
//! came from was taken (a chair pulled out into the way, a chair pushed into a standing spot).
//! The world's truth changes at the given simulated time: the simulated range sensor, the base's
//! contact check and the later camera frames see the chair where it now stands; the onboard map
//! does not.

use std::fmt;
use std::str::FromStr;
use std::time::Duration;

use serde::{Deserialize, Serialize};
use world::Scene;

/// One move of a chair of the world's scene.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ChairMove {
    /// When (simulated seconds after the world's clock started).
    pub at_s: f64,
    /// Which chair: its index in the world's scene (the map's chairs, then the unmapped ones).
    pub chair: usize,
    /// Where it goes: x (m).
    pub x_m: f64,
    /// y (m).
    pub y_m: f64,
    /// Its yaw (rad).
    pub yaw_rad: f64,
}

/// Why a chair move given as text was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("chair move {text:?}: {why} (expected AT_S:CHAIR:X:Y:YAW, e.g. 12.5:3:1.0:5.2:0.3)")]
pub struct ChairMoveError {
    text: String,
    why: String,
}

impl FromStr for ChairMove {
    type Err = ChairMoveError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let err = |why: String| ChairMoveError {
            text: s.to_owned(),
            why,
        };
        let parts: Vec<&str> = s.split(':').collect();
        let [at, chair, x, y, yaw] = parts.as_slice() else {
            return Err(err(format!("{} fields", parts.len())));
        };
        let num = |name: &str, v: &str| -> Result<f64, ChairMoveError> {
            match v.parse::<f64>() {
                Ok(n) if n.is_finite() => Ok(n),
                _ => Err(err(format!("{name} {v:?} is not a finite number"))),
            }
        };
        let at_s = num("AT_S", at)?;
        if at_s < 0.0 {
            return Err(err(format!("AT_S {at_s} is negative")));
        }
        let chair = chair
            .parse::<usize>()
            .map_err(|_| err(format!("CHAIR {chair:?} is not an index")))?;
        Ok(Self {
            at_s,
            chair,
            x_m: num("X", x)?,
            y_m: num("Y", y)?,
            yaw_rad: num("YAW", yaw)?,
        })
    }
}

impl fmt::Display for ChairMove {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}:{}:{}:{}:{}",
            self.at_s, self.chair, self.x_m, self.y_m, self.yaw_rad
        )
    }
}

impl ChairMove {
    /// Checks the move against the scene: the chair exists, and where it goes is inside the
    /// room.
    pub fn check(&self, scene: &Scene) -> Result<(), ChairMoveError> {
        let err = |why: String| ChairMoveError {
            text: self.to_string(),
            why,
        };
        if self.chair >= scene.chairs.len() {
            return Err(err(format!(
                "the scene has {} chairs (0..{})",
                scene.chairs.len(),
                scene.chairs.len()
            )));
        }
        if !scene.room.contains(self.x_m, self.y_m) {
            return Err(err(format!(
                "({}, {}) is outside the room",
                self.x_m, self.y_m
            )));
        }
        Ok(())
    }
}

/// The moves still to come, in time order.
#[derive(Debug, Clone, Default)]
pub struct Mover {
    pending: Vec<ChairMove>,
}

impl Mover {
    /// The moves of a run (any order).
    pub fn new(moves: &[ChairMove]) -> Self {
        let mut pending = moves.to_vec();
        // Latest first: the next due is popped from the end.
        pending.sort_by(|a, b| b.at_s.total_cmp(&a.at_s));
        Self { pending }
    }

    /// Applies to `scene` every move due by `now`; true if the scene changed.
    pub fn apply_due(&mut self, now: Duration, scene: &mut Scene) -> bool {
        let mut changed = false;
        while self
            .pending
            .last()
            .is_some_and(|m| m.at_s <= now.as_secs_f64())
        {
            let Some(m) = self.pending.pop() else { break };
            if let Some(chair) = scene.chairs.get_mut(m.chair) {
                log::info!(
                    "world: chair {} moved at {:.2} s from ({:.2}, {:.2}) to ({:.2}, {:.2})",
                    m.chair,
                    now.as_secs_f64(),
                    chair.x_m,
                    chair.y_m,
                    m.x_m,
                    m.y_m
                );
                chair.x_m = m.x_m;
                chair.y_m = m.y_m;
                chair.yaw_rad = m.yaw_rad;
                changed = true;
            }
        }
        changed
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failure panics with its message

    use super::*;

    #[test]
    fn a_move_reads_back_and_bad_text_names_what_is_wrong() {
        let m: ChairMove = "12.5:3:1:5.2:0.3".parse().unwrap();
        assert_eq!(m.chair, 3);
        assert_eq!(m.to_string().parse::<ChairMove>().unwrap(), m);
        for (bad, says) in [
            ("12.5:3:1:5.2", "4 fields"),
            ("x:3:1:5.2:0.3", "AT_S"),
            ("1:-3:1:5.2:0.3", "CHAIR"),
            ("1:3:nan:5.2:0.3", "X"),
            ("-1:3:1:5.2:0.3", "negative"),
        ] {
            let e = bad.parse::<ChairMove>().unwrap_err().to_string();
            assert!(e.contains(says), "{bad}: {e}");
        }
    }

    #[test]
    fn moves_apply_in_time_order_once_due() {
        let mut scene = Scene::empty_paper_room();
        scene.chairs.push(world::Chair::new(1.0, 3.0, 0.0));
        let mut mover = Mover::new(&["5:0:2:3:0".parse().unwrap(), "2:0:1.5:3:0".parse().unwrap()]);
        assert!(!mover.apply_due(Duration::from_secs(1), &mut scene));
        assert!(mover.apply_due(Duration::from_secs(2), &mut scene));
        assert_eq!(scene.chairs[0].x_m, 1.5);
        assert!(mover.apply_due(Duration::from_secs(9), &mut scene));
        assert_eq!(scene.chairs[0].x_m, 2.0);
        assert!(!mover.apply_due(Duration::from_secs(10), &mut scene));
        let outside: ChairMove = "1:0:50:3:0".parse().unwrap();
        assert!(
            outside
                .check(&scene)
                .unwrap_err()
                .to_string()
                .contains("outside the room")
        );
        let missing: ChairMove = "1:4:1:3:0".parse().unwrap();
        assert!(
            missing
                .check(&scene)
                .unwrap_err()
                .to_string()
                .contains("1 chairs")
        );
    }
}

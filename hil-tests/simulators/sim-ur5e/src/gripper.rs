//! Simulated Robotiq 2F-140 behind the URCap socket protocol (port 63352).
//!
//! Fingers move at 30..250 mm/s (SPE 0..255) towards the requested position (PRE) once
//! activated and GTO = 1; an object of configurable width between the fingers stops them
//! while closing (OBJ = 2). Protocol replies: `ack` for `SET`, `<VAR> <value>` for `GET`.

/// Stroke of the 2F-140 (m).
pub const STROKE_M: f64 = 0.140;
/// Activation takes this long (s).
const ACTIVATION_S: f64 = 0.5;

/// Gripper state.
#[derive(Debug, Clone, PartialEq)]
pub struct GripperModel {
    act: bool,
    sta: u8,
    activation_left_s: f64,
    gto: bool,
    pre: u8,
    spe: u8,
    force: u8,
    pos: f64,
    obj: u8,
    flt: u8,
    /// Width of an object between the fingers (m), if any.
    pub object_width_m: Option<f64>,
}

impl Default for GripperModel {
    fn default() -> Self {
        Self {
            act: false,
            sta: 0,
            activation_left_s: 0.0,
            gto: false,
            pre: 0,
            spe: 255,
            force: 128,
            pos: 0.0,
            obj: 0,
            flt: 0,
            object_width_m: None,
        }
    }
}

impl GripperModel {
    /// Finger gap (m).
    pub fn opening_m(&self) -> f64 {
        STROKE_M * (1.0 - self.pos / 255.0)
    }

    /// Position (0 open .. 255 closed) where the fingers touch the object, if any.
    fn contact_pos(&self) -> Option<f64> {
        self.object_width_m
            .filter(|w| *w > 0.0 && *w < STROKE_M)
            .map(|w| 255.0 * (1.0 - w / STROKE_M))
    }

    /// Activated (STA = 3): the gripper can be at work on an object.
    pub fn is_active(&self) -> bool {
        self.sta == 3
    }

    /// Fault injection: FLT reads `code` and the fingers stop until the next activation.
    pub fn inject_fault(&mut self, code: u8) {
        self.flt = code;
    }

    /// Advances the fingers by `dt` seconds.
    pub fn step(&mut self, dt: f64) {
        if self.flt != 0 {
            return;
        }
        if self.sta == 1 {
            self.activation_left_s -= dt;
            if self.activation_left_s <= 0.0 {
                self.sta = 3;
            }
            return;
        }
        if self.sta != 3 || !self.gto || self.obj != 0 {
            return;
        }
        let speed_mps = 0.030 + 0.220 * f64::from(self.spe) / 255.0;
        let step = speed_mps / STROKE_M * 255.0 * dt;
        let target = f64::from(self.pre);
        if self.pos < target {
            // Closing.
            let next = (self.pos + step).min(target);
            match self.contact_pos() {
                Some(c) if c < target && next >= c && self.pos <= c => {
                    self.pos = c;
                    self.obj = 2;
                }
                _ => {
                    self.pos = next;
                    if next >= target {
                        self.obj = 3;
                    }
                }
            }
        } else {
            let next = (self.pos - step).max(target);
            self.pos = next;
            if next <= target {
                self.obj = 3;
            }
        }
    }

    /// Handles one protocol line; returns the reply line (without newline).
    pub fn handle(&mut self, line: &str) -> String {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("SET") => {
                let rest: Vec<&str> = words.collect();
                if rest.is_empty() || rest.len() % 2 != 0 {
                    return "?".into();
                }
                let mut pairs = Vec::new();
                for pair in rest.chunks(2) {
                    match pair[1].parse::<u8>() {
                        Ok(v) => pairs.push((pair[0], v)),
                        Err(_) => return "?".into(),
                    }
                }
                for (name, v) in pairs {
                    if !self.set(name, v) {
                        return "?".into();
                    }
                }
                "ack".into()
            }
            Some("GET") => match words.next() {
                Some(name) => match self.get(name) {
                    Some(v) => format!("{name} {v}"),
                    None => "?".into(),
                },
                None => "?".into(),
            },
            _ => "?".into(),
        }
    }

    fn set(&mut self, name: &str, v: u8) -> bool {
        match name {
            "ACT" => {
                let on = v != 0;
                if on && !self.act {
                    self.sta = 1;
                    self.activation_left_s = ACTIVATION_S;
                    self.flt = 0;
                } else if !on {
                    self.sta = 0;
                    self.gto = false;
                }
                self.act = on;
            }
            "GTO" => {
                self.gto = v != 0;
                if self.gto {
                    // A new go-to starts a motion: object status is "moving" again.
                    self.obj = 0;
                }
            }
            "POS" => {
                self.pre = v;
                self.obj = 0;
            }
            "SPE" => self.spe = v,
            "FOR" => self.force = v,
            "ATR" | "ARD" | "MOD" | "SID" => {}
            _ => return false,
        }
        true
    }

    fn get(&self, name: &str) -> Option<u32> {
        Some(match name {
            "ACT" => u32::from(self.act),
            "GTO" => u32::from(self.gto),
            "STA" => u32::from(self.sta),
            "PRE" => u32::from(self.pre),
            "POS" => self.pos.round() as u32,
            "SPE" => u32::from(self.spe),
            "FOR" => u32::from(self.force),
            "OBJ" => u32::from(self.obj),
            "FLT" => u32::from(self.flt),
            _ => return None,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(g: &mut GripperModel, s: f64) {
        for _ in 0..(s / 0.002) as usize {
            g.step(0.002);
        }
    }

    #[test]
    fn activate_close_on_object_then_open() {
        let mut g = GripperModel {
            object_width_m: Some(0.05),
            ..GripperModel::default()
        };
        assert_eq!(g.handle("SET ACT 1"), "ack");
        assert_eq!(g.handle("GET STA"), "STA 1");
        run(&mut g, 0.6);
        assert_eq!(g.handle("GET STA"), "STA 3");
        assert_eq!(g.handle("SET POS 255 SPE 255 FOR 100 GTO 1"), "ack");
        run(&mut g, 1.0);
        assert_eq!(g.handle("GET OBJ"), "OBJ 2");
        assert!((g.opening_m() - 0.05).abs() < 1e-9);
        assert_eq!(g.handle("SET POS 0 GTO 1"), "ack");
        run(&mut g, 1.0);
        assert_eq!(g.handle("GET OBJ"), "OBJ 3");
        assert_eq!(g.handle("GET POS"), "POS 0");
    }

    #[test]
    fn bad_lines_get_a_question_mark() {
        let mut g = GripperModel::default();
        assert_eq!(g.handle("SET POS"), "?");
        assert_eq!(g.handle("SET POS 300"), "?");
        assert_eq!(g.handle("GET XYZ"), "?");
        assert_eq!(g.handle("HELLO"), "?");
    }

    #[test]
    fn fingers_do_not_move_before_activation() {
        let mut g = GripperModel::default();
        g.handle("SET POS 255 GTO 1");
        run(&mut g, 1.0);
        assert_eq!(g.handle("GET POS"), "POS 0");
    }
}

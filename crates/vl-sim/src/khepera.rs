//! The Khepera I/II serial protocol (BIOS 5.x), answered by the simulated
//! robot: one upper-case letter, optional `,int` arguments, CR or LF; the
//! reply is the letter in lower case, `,values`, CRLF.
//!
//! [`Khepera`] is the protocol alone, line in → reply out, over a [`World`]
//! the caller advances; the emulator in `vl khepera-emu` puts it on a
//! pseudo-terminal in real time.

use crate::world::World;
use vl_core::{
    CommandError, KheperaCommand, KheperaReply, LedAction, MAX_PROFILE_ACCEL,
    MAX_PULSES_PER_PERIOD as MAX_SPEED, MotorMode, MotorStatus, WheelMove, WheelSpeeds,
};

/// What `B` answers: BIOS 5.02, protocol 5.01.
const BIOS: &str = "5.02";
const PROTOCOL: &str = "5.01";

/// Ambient light reading in the simulated arena's even lighting (lower = brighter).
const AMBIENT: u16 = 480;

/// The speed profile position moves follow (`J`): the firmware's default
/// top speed is 20 pulses per 10 ms and its acceleration 64, in units of
/// 1/256 pulse per 10 ms per 10 ms.
const DEFAULT_PROFILE: [i64; 2] = [20, 64];

/// A wheel within this many pulses of its position target is on target.
const ON_TARGET_PULSES: i64 = 1;

/// A Khepera answering its serial protocol. Its motors are the simulated
/// robot's: a speed controller (`D`), or position controllers (`C`) that
/// move each wheel along a trapezoid (`J`) to its target and stop there,
/// whatever happens to the line.
pub struct Khepera {
    world: World,
    /// Encoder counts set by `G`, subtracted from the wheels' travel.
    counter_origin: [i64; 2],
    /// Commanded speeds, pulses per 10 ms (speed mode).
    speed: [i64; 2],
    /// Position targets, pulses, while the position controllers have the wheels.
    targets: Option<[i64; 2]>,
    /// Per motor: top speed and acceleration of position moves (`J`).
    profile: [[i64; 2]; 2],
    leds: [bool; 2],
}

impl Khepera {
    pub fn new(world: World) -> Self {
        Khepera {
            world,
            counter_origin: [0; 2],
            speed: [0; 2],
            targets: None,
            profile: [DEFAULT_PROFILE; 2],
            leds: [false; 2],
        }
    }

    /// Advances the robot one control period.
    pub fn step(&mut self) {
        self.world.step();
    }

    /// Asks the world's speed controller for the commanded pulse rates.
    fn command_speeds(&mut self) {
        let robot = self.world.robot();
        let wheels = WheelSpeeds {
            left_mm_s: robot.speed_mm_s(self.speed[0]),
            right_mm_s: robot.speed_mm_s(self.speed[1]),
        };
        self.world.set_wheels(wheels);
    }

    /// Hands the position controllers the targets and the profile.
    fn command_moves(&mut self, targets: [i64; 2]) {
        let robot = self.world.robot();
        let per = robot.mm_per_pulse;
        let moves = [0, 1].map(|i| WheelMove {
            target_mm: (targets[i] + self.counter_origin[i]) as f64 * per,
            top_mm_s: robot.speed_mm_s(self.profile[i][0]),
            accel_mm_s2: self.profile[i][1] as f64 * robot.profile_accel_unit(),
        });
        self.targets = Some(targets);
        self.world.move_wheels(moves);
    }

    pub fn world(&self) -> &World {
        &self.world
    }

    pub fn world_mut(&mut self) -> &mut World {
        &mut self.world
    }

    /// Whether LED `n` is lit.
    pub fn led(&self, n: usize) -> bool {
        self.leds.get(n).copied().unwrap_or(false)
    }

    fn counters(&self) -> [i64; 2] {
        let per = self.world.robot().mm_per_pulse;
        let travel = self.world.wheel_travel_mm();
        [
            (travel[0] / per).round() as i64 - self.counter_origin[0],
            (travel[1] / per).round() as i64 - self.counter_origin[1],
        ]
    }

    /// The reply to one command line (without its line ending), or None for
    /// an empty line, which the firmware ignores.
    pub fn handle(&mut self, line: &str) -> Option<String> {
        let reply = match KheperaCommand::parse(line) {
            Ok(None) => return None,
            Ok(Some(command)) => self.execute(command),
            Err(refused) => KheperaReply::Refused(refused.to_string()),
        };
        Some(reply.encode())
    }

    /// Carries out one command as the firmware does.
    pub fn execute(&mut self, command: KheperaCommand) -> KheperaReply {
        use KheperaCommand as K;
        match command {
            // The controllers' gains (`A`, `F`) are answered; the simulated
            // controllers are tuned to the motors' response instead.
            K::SpeedGains { .. } | K::PositionGains { .. } => {}
            K::SpeedProfile { top, accel } => {
                for wheel in 0..2 {
                    self.profile[wheel] = [
                        top[wheel].clamp(0, MAX_SPEED),
                        accel[wheel].clamp(1, MAX_PROFILE_ACCEL),
                    ];
                }
                // A move under way goes on with the new profile.
                if let Some(targets) = self.targets {
                    self.command_moves(targets);
                }
            }
            K::MoveTo { left, right } => {
                // Targets a 32-bit counter can hold.
                let limit = i64::from(i32::MAX);
                self.command_moves([left.clamp(-limit, limit), right.clamp(-limit, limit)]);
            }
            K::Version => {
                return KheperaReply::Version {
                    bios: BIOS.to_owned(),
                    protocol: PROTOCOL.to_owned(),
                };
            }
            K::SetSpeed { left, right } => {
                self.speed = [
                    left.clamp(-MAX_SPEED, MAX_SPEED),
                    right.clamp(-MAX_SPEED, MAX_SPEED),
                ];
                self.targets = None;
                self.command_speeds();
            }
            K::ReadSpeed => return KheperaReply::Speed(self.wheel_pulses()),
            K::SetCounters { left, right } => {
                let now = self.counters();
                self.counter_origin[0] += now[0] - left;
                self.counter_origin[1] += now[1] - right;
                // Targets are counts: the same counts now lie elsewhere.
                if let Some(targets) = self.targets {
                    self.command_moves(targets);
                }
            }
            K::ReadCounters => return KheperaReply::Counters(self.counters()),
            K::ReadStatus => {
                let actual = self.wheel_pulses();
                let counts = self.counters();
                let motor = |i: usize| match self.targets {
                    None => {
                        let error = self.speed[i] - actual[i];
                        MotorStatus {
                            on_target: error == 0,
                            mode: MotorMode::Speed,
                            error,
                        }
                    }
                    Some(targets) => {
                        let error = targets[i] - counts[i];
                        MotorStatus {
                            on_target: error.abs() <= ON_TARGET_PULSES && actual[i] == 0,
                            mode: MotorMode::Position,
                            error,
                        }
                    }
                };
                return KheperaReply::Status([motor(0), motor(1)]);
            }
            K::Led { led, action } => {
                let Some(lit) = self.leds.get_mut(usize::from(led)) else {
                    return KheperaReply::Refused(CommandError::BadArguments.to_string());
                };
                *lit = match action {
                    LedAction::Off => false,
                    LedAction::On => true,
                    LedAction::Toggle => !*lit,
                };
            }
            K::ReadProximity => return KheperaReply::Proximity(self.world.proximity()),
            K::ReadAmbient => {
                return KheperaReply::Ambient(vec![AMBIENT; self.world.robot().sensors.len()]);
            }
        }
        KheperaReply::Done(command.letter().to_ascii_lowercase())
    }

    /// The wheels' actual speeds, pulses per 10 ms.
    fn wheel_pulses(&self) -> [i64; 2] {
        let w = self.world.wheels();
        let robot = self.world.robot();
        [
            robot.pulses_per_period(w.left_mm_s),
            robot.pulses_per_period(w.right_mm_s),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vl_core::{Arena, RobotModel};

    fn khepera() -> Khepera {
        Khepera::new(World::new(Arena::navigation(), RobotModel::khepera_ii(), 1).unwrap())
    }

    #[test]
    fn answers_the_bios_commands() {
        let mut k = khepera();
        assert_eq!(k.handle("B").unwrap(), "b,5.02,5.01");
        assert_eq!(k.handle(""), None);
        assert_eq!(k.handle("X").unwrap(), "z,Command not found");
        assert_eq!(k.handle("D,ten,10").unwrap(), "z,Bad arguments");
        assert_eq!(k.handle("D,10").unwrap(), "z,Bad arguments");
        assert_eq!(k.handle("D,10,10").unwrap(), "d");
        k.world_mut().run_for(1.0);
        // 10 pulses per 10 ms for a second: 1000 pulses on each wheel.
        let counts = |k: &mut Khepera| -> Vec<i64> {
            let h = k.handle("H").unwrap();
            h.strip_prefix("h,")
                .unwrap()
                .split(',')
                .map(|v| v.parse().unwrap())
                .collect()
        };
        // The speed controller's 30 ms lag costs a few pulses at the start…
        assert!(counts(&mut k).iter().all(|&c| (960..=1000).contains(&c)));
        // …then the counters grow by exactly 10 pulses per 10 ms.
        let before = counts(&mut k);
        k.world_mut().run_for(1.0);
        let after = counts(&mut k);
        assert_eq!((after[0] - before[0], after[1] - before[1]), (1000, 1000));
        assert_eq!(k.handle("E").unwrap(), "e,10,10");
        assert_eq!(k.handle("K").unwrap(), "k,1,1,0,1,1,0");
        assert_eq!(k.handle("G,0,0").unwrap(), "g");
        assert_eq!(k.handle("H").unwrap(), "h,0,0");
        assert_eq!(k.handle("L,1,2").unwrap(), "l");
        assert!(k.led(1));
        let n = k.handle("N").unwrap();
        assert!(n.starts_with("n,") && n.split(',').count() == 9, "{n}");
        assert_eq!(
            k.handle("D,500,-500").unwrap(),
            "d",
            "speeds beyond 127 are clamped"
        );
        k.world_mut().run_for(0.5);
        assert_eq!(k.handle("E").unwrap(), "e,127,-127");
    }

    #[test]
    fn position_moves_reach_their_targets() {
        let mut k = khepera();
        assert_eq!(k.handle("G,0,0").unwrap(), "g");
        assert_eq!(k.handle("C,3000,-1500").unwrap(), "c");
        let mut top = 0;
        for _ in 0..400 {
            k.step();
            let e = k.handle("E").unwrap();
            let left: i64 = e[2..].split(',').next().unwrap().parse().unwrap();
            top = top.max(left);
        }
        let h = k.handle("H").unwrap();
        let counts: Vec<i64> = h[2..].split(',').map(|v| v.parse().unwrap()).collect();
        assert!(
            (counts[0] - 3000).abs() <= 2 && (counts[1] + 1500).abs() <= 2,
            "{h}"
        );
        assert_eq!(top, 20, "the default profile's top speed");
        let status = k.handle("K").unwrap();
        assert!(
            status.starts_with("k,1,0,") && status.contains(",1,0,"),
            "{status}"
        );
        // A slower profile, then a speed command takes the motors back.
        assert_eq!(k.handle("J,5,64,5,64").unwrap(), "j");
        k.handle("C,4000,1000").unwrap();
        for _ in 0..40 {
            k.step();
        }
        assert_eq!(k.handle("E").unwrap(), "e,5,5");
        k.handle("D,0,0").unwrap();
        assert!(k.handle("K").unwrap().starts_with("k,0,1,-5,"));
    }
}

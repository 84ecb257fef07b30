//! A user's wheel controller — a WebAssembly module speaking interface
//! version 1 (`docs/controllers.md`) — checked before it runs and run in a
//! bounded sandbox: a fuel budget a step (deterministic: the twin and the
//! robot cut a step at the same instruction), a memory cap, an optional
//! wall-clock deadline (the Host's, never the twin's), one import
//! (`env.vl_log`, rate-limited), and whatever it answers checked finite.
//!
//! `Module::load` checks a file once; `Module::start` gives an `Instance`
//! per run (a forecast starts one per seed), which implements
//! `vl_core::Controller`.

use std::time::{Duration, Instant};

use thiserror::Error;
use vl_core::{
    ABI_VERSION, Answer, COMMAND_WORDS, Controller, ControllerFault, MAX_MODULE_BYTES, ModuleHash,
    OBSERVATION_WORDS, Observation, WheelSpeeds,
};
use wasmi::{
    Caller, Config, Engine, ExternType, Linker, Memory, Store, StoreLimits, StoreLimitsBuilder,
    TrapCode, TypedFunc, ValType,
};

/// The module and its log may keep at most this many lines a second; more
/// are counted, not kept.
pub const LOG_LINES_PER_S: usize = 10;
/// A logged line is cut to this many bytes.
pub const LOG_LINE_BYTES: usize = 200;
/// The one function a module may import.
const LOG_IMPORT: (&str, &str) = ("env", "vl_log");

/// What a running module may use.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Budget {
    /// Instructions (wasmi's fuel) a step may execute; `vl_init` gets ten
    /// times as many.
    pub fuel_per_step: u64,
    /// Linear memory, bytes: growing past it ends the run.
    pub memory_bytes: usize,
    /// Wall-clock time a step may take; none for the twin, whose runs must
    /// not depend on how busy the machine is.
    pub deadline: Option<Duration>,
}

impl Budget {
    /// On the Host: a step of at most a million instructions (about 2 ms
    /// of a release build here) and 50 ms of the clock, 16 MiB of memory.
    /// The robot stops after three steps (60 ms) without an answer anyway:
    /// the deadline ends a controller that keeps missing them, generous
    /// enough that a busy machine's pause alone does not.
    pub const LAB: Budget = Budget {
        fuel_per_step: 1_000_000,
        memory_bytes: 16 << 20,
        deadline: Some(Duration::from_millis(50)),
    };

    /// On the twin: the lab's budget without its clock.
    pub const TWIN: Budget = Budget {
        deadline: None,
        ..Budget::LAB
    };
}

/// Why a file is not a controller the lab runs.
#[derive(Debug, Error, PartialEq)]
pub enum LoadError {
    #[error("the module is {got} bytes; a controller may have at most {max} (2 MiB)")]
    TooLarge { got: usize, max: usize },
    #[error("not a WebAssembly module (nor its text format): {0}")]
    NotWasm(String),
    #[error("the module imports {0}: a controller may import only env.vl_log(ptr: i32, len: i32)")]
    ForbiddenImport(String),
    #[error("the module does not export {name} as {wanted}")]
    MissingExport {
        name: &'static str,
        wanted: &'static str,
    },
    #[error("the module speaks interface version {0}; this lab speaks version 1")]
    WrongAbi(i32),
    #[error("the module's {what} address {address} leaves no room for {bytes} bytes in its memory")]
    OutOfMemory {
        what: &'static str,
        address: u32,
        bytes: usize,
    },
    #[error("the module could not start: {0}")]
    Start(ControllerFault),
}

/// A module that does not start is the run's fault: `vl_init`'s own, or
/// what kept it from starting, in words.
impl From<LoadError> for ControllerFault {
    fn from(e: LoadError) -> ControllerFault {
        match e {
            LoadError::Start(fault) => fault,
            other => ControllerFault::Trapped(other.to_string()),
        }
    }
}

/// A module checked to be a controller the lab may run.
#[derive(Clone)]
pub struct Module {
    engine: Engine,
    module: wasmi::Module,
    hash: ModuleHash,
    bytes: usize,
}

impl std::fmt::Debug for Module {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Module({}, {} bytes)", self.hash(), self.bytes)
    }
}

/// The exports version 1 needs, and their types (params, results).
const EXPORTS: [(&str, &[ValType], &[ValType], &str); 4] = [
    ("vl_abi", &[], &[ValType::I32], "a function () -> i32"),
    (
        "vl_observation",
        &[],
        &[ValType::I32],
        "a function () -> i32",
    ),
    ("vl_command", &[], &[ValType::I32], "a function () -> i32"),
    ("vl_step", &[], &[ValType::I32], "a function () -> i32"),
];

impl Module {
    /// Checks `bytes` (binary or text): its size, that it is WebAssembly,
    /// its imports and exports. Nothing of it runs yet.
    pub fn load(bytes: &[u8]) -> Result<Module, LoadError> {
        if bytes.len() > MAX_MODULE_BYTES {
            return Err(LoadError::TooLarge {
                got: bytes.len(),
                max: MAX_MODULE_BYTES,
            });
        }
        let mut config = Config::default();
        config.consume_fuel(true);
        let engine = Engine::new(&config);
        // The parser is not ours: whatever it makes of a crafted file, the
        // Host goes on (the engine is dropped with the file if it panics).
        let parse = std::panic::AssertUnwindSafe(|| wasmi::Module::new(&engine, bytes));
        let parsed = std::panic::catch_unwind(parse)
            .map_err(|_| LoadError::NotWasm("the parser gave up on it".into()))?;
        let module = parsed.map_err(|e| LoadError::NotWasm(e.to_string()))?;
        for import in module.imports() {
            let allowed = (import.module(), import.name()) == LOG_IMPORT
                && matches!(import.ty(), ExternType::Func(f)
                    if f.params() == [ValType::I32, ValType::I32] && f.results().is_empty());
            if !allowed {
                return Err(LoadError::ForbiddenImport(format!(
                    "{}.{}",
                    import.module(),
                    import.name()
                )));
            }
        }
        let export = |name: &str| {
            module
                .exports()
                .find(|e| e.name() == name)
                .map(|e| e.ty().clone())
        };
        if !matches!(export("memory"), Some(ExternType::Memory(_))) {
            return Err(LoadError::MissingExport {
                name: "memory",
                wanted: "a memory",
            });
        }
        for (name, params, results, wanted) in EXPORTS {
            let fits = matches!(export(name), Some(ExternType::Func(f))
                if f.params() == params && f.results() == results);
            if !fits {
                return Err(LoadError::MissingExport { name, wanted });
            }
        }
        if let Some(init) = export("vl_init") {
            let fits = matches!(init, ExternType::Func(f)
                if f.params().is_empty() && f.results() == [ValType::I32]);
            if !fits {
                return Err(LoadError::MissingExport {
                    name: "vl_init",
                    wanted: "a function () -> i32, if at all",
                });
            }
        }
        Ok(Module {
            engine,
            module,
            hash: ModuleHash::of(bytes),
            bytes: bytes.len(),
        })
    }

    /// The SHA-256 of the file: what a definition, a recording and a
    /// regrade name the module by.
    pub fn hash(&self) -> ModuleHash {
        self.hash
    }

    /// The file's size, bytes.
    pub fn len(&self) -> usize {
        self.bytes
    }

    /// Whether the file was empty (it never is once loaded).
    pub fn is_empty(&self) -> bool {
        self.bytes == 0
    }

    /// A fresh controller at each call, within `budget`: what the twin's
    /// forecast starts for each seed.
    pub fn controllers(
        &self,
        budget: Budget,
    ) -> impl Fn() -> Result<Box<dyn Controller>, ControllerFault> + Sync + '_ {
        move || Ok(Box::new(self.start(budget)?) as Box<dyn Controller>)
    }

    /// A fresh instance for one run: instantiated, `vl_init` called, its
    /// version and addresses checked.
    pub fn start(&self, limits: Budget) -> Result<Instance, LoadError> {
        let state = State {
            limits: StoreLimitsBuilder::new()
                .memory_size(limits.memory_bytes)
                .trap_on_grow_failure(true)
                .build(),
            log: Vec::new(),
            log_window: (0.0, 0),
            now_s: 0.0,
            dropped: 0,
        };
        let mut store = Store::new(&self.engine, state);
        store.limiter(|s| &mut s.limits);
        let mut linker = Linker::<State>::new(&self.engine);
        linker
            .func_wrap(LOG_IMPORT.0, LOG_IMPORT.1, log)
            .expect("one definition of vl_log");
        let fuel = limits.fuel_per_step.saturating_mul(10);
        store.set_fuel(fuel).expect("fuel metering is on");
        let fault = |e: wasmi::Error, store: &Store<State>| {
            LoadError::Start(fault_of(&e, store, fuel, limits.memory_bytes))
        };
        let instance = linker
            .instantiate_and_start(&mut store, &self.module)
            .map_err(|e| fault(e, &store))?;
        let func = |name: &'static str| -> Result<TypedFunc<(), i32>, LoadError> {
            instance
                .get_typed_func::<(), i32>(&store, name)
                .map_err(|_| LoadError::MissingExport {
                    name,
                    wanted: "a function () -> i32",
                })
        };
        let (abi, observation, command, step) = (
            func("vl_abi")?,
            func("vl_observation")?,
            func("vl_command")?,
            func("vl_step")?,
        );
        let memory = instance
            .get_memory(&store, "memory")
            .ok_or(LoadError::MissingExport {
                name: "memory",
                wanted: "a memory",
            })?;
        let version = abi.call(&mut store, ()).map_err(|e| fault(e, &store))?;
        if version != ABI_VERSION {
            return Err(LoadError::WrongAbi(version));
        }
        if let Ok(init) = instance.get_typed_func::<(), i32>(&store, "vl_init") {
            let status = init.call(&mut store, ()).map_err(|e| fault(e, &store))?;
            if status != 0 {
                return Err(LoadError::Start(ControllerFault::InitFailed(status)));
            }
        }
        let mut within = |what: &'static str, f: TypedFunc<(), i32>, words: usize| {
            let address = f.call(&mut store, ()).map_err(|e| fault(e, &store))? as u32;
            let bytes = words * 8;
            if (address as usize).saturating_add(bytes) > memory.data_size(&store) {
                return Err(LoadError::OutOfMemory {
                    what,
                    address,
                    bytes,
                });
            }
            Ok(address as usize)
        };
        let observation = within("observation", observation, OBSERVATION_WORDS)?;
        let command = within("command", command, COMMAND_WORDS)?;
        Ok(Instance {
            store,
            memory,
            step,
            observation,
            command,
            limits,
            fuel_used: 0,
        })
    }
}

/// What the store keeps for the module's imports and limits.
struct State {
    limits: StoreLimits,
    /// Lines logged and not yet taken.
    log: Vec<String>,
    /// The second lines are being counted in (its start, s), and how many.
    log_window: (f64, usize),
    /// The run's time at the step under way, s.
    now_s: f64,
    /// Lines over the rate, not kept.
    dropped: u64,
}

/// `env.vl_log(ptr, len)`: a line of the module's, kept if within the rate.
fn log(mut caller: Caller<'_, State>, ptr: i32, len: i32) {
    let Some(memory) = caller.get_export("memory").and_then(|e| e.into_memory()) else {
        return;
    };
    let len = (len.max(0) as usize).min(LOG_LINE_BYTES);
    let mut bytes = vec![0; len];
    let read = memory
        .read(&caller, ptr as u32 as usize, &mut bytes)
        .is_ok();
    let state = caller.data_mut();
    let (start, count) = &mut state.log_window;
    if state.now_s - *start >= 1.0 {
        (*start, *count) = (state.now_s, 0);
    }
    if !read || *count >= LOG_LINES_PER_S {
        state.dropped += 1;
        return;
    }
    *count += 1;
    let text = String::from_utf8_lossy(&bytes);
    state
        .log
        .push(text.chars().filter(|c| !c.is_control()).collect());
}

/// A running controller: one run's instance of a `Module`.
pub struct Instance {
    store: Store<State>,
    memory: Memory,
    step: TypedFunc<(), i32>,
    observation: usize,
    command: usize,
    limits: Budget,
    fuel_used: u64,
}

impl std::fmt::Debug for Instance {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Instance(fuel used {})", self.fuel_used)
    }
}

impl Instance {
    /// The lines the module logged since the last call (at most
    /// `LOG_LINES_PER_S` a second), and how many more it tried to.
    pub fn take_log(&mut self) -> (Vec<String>, u64) {
        let state = self.store.data_mut();
        (
            std::mem::take(&mut state.log),
            std::mem::take(&mut state.dropped),
        )
    }

    /// Instructions the last step executed.
    pub fn fuel_used(&self) -> u64 {
        self.fuel_used
    }
}

impl Controller for Instance {
    fn step(&mut self, seen: &Observation) -> Result<Answer, ControllerFault> {
        let budget = self.limits.fuel_per_step;
        let cap = self.limits.memory_bytes;
        self.store.data_mut().now_s = seen.t_s;
        // Laid out on the stack: nothing is allocated on the control loop's rate.
        let mut words = [0u8; OBSERVATION_WORDS * 8];
        for (bytes, word) in words.chunks_exact_mut(8).zip(seen.words()) {
            bytes.copy_from_slice(&word.to_le_bytes());
        }
        self.memory
            .write(&mut self.store, self.observation, &words)
            .map_err(|e| ControllerFault::Trapped(e.to_string()))?;
        self.store.set_fuel(budget).expect("fuel metering is on");
        let began = Instant::now();
        let said = self.step.call(&mut self.store, ());
        let took = began.elapsed();
        self.fuel_used = budget - self.store.get_fuel().unwrap_or(0);
        let said = said.map_err(|e| fault_of(&e, &self.store, budget, cap))?;
        if let Some(deadline) = self.limits.deadline
            && took > deadline
        {
            return Err(ControllerFault::TooSlow {
                took_ms: took.as_secs_f64() * 1e3,
                deadline_ms: deadline.as_secs_f64() * 1e3,
            });
        }
        let mut command = [0u8; COMMAND_WORDS * 8];
        self.memory
            .read(&self.store, self.command, &mut command)
            .map_err(|e| ControllerFault::Trapped(e.to_string()))?;
        let word =
            |i: usize| f64::from_le_bytes(command[i * 8..i * 8 + 8].try_into().expect("8 bytes"));
        let (left, right) = (word(0), word(1));
        if !left.is_finite() || !right.is_finite() {
            return Err(ControllerFault::NotFinite { left, right });
        }
        Ok(Answer {
            wheels: WheelSpeeds {
                left_mm_s: left,
                right_mm_s: right,
            },
            finished: said == 1,
        })
    }
}

/// What stopped a call, in the lab's words.
fn fault_of(e: &wasmi::Error, store: &Store<State>, budget: u64, cap: usize) -> ControllerFault {
    match e.as_trap_code() {
        Some(TrapCode::OutOfFuel) => ControllerFault::OutOfFuel { budget },
        Some(TrapCode::GrowthOperationLimited) => ControllerFault::MemoryCap { cap_mib: cap >> 20 },
        Some(code) => ControllerFault::Trapped(code.to_string()),
        None if matches!(store.get_fuel(), Ok(0)) => ControllerFault::OutOfFuel { budget },
        None if e.to_string().contains("limit") => {
            ControllerFault::MemoryCap { cap_mib: cap >> 20 }
        }
        None => ControllerFault::Trapped(e.to_string()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use vl_core::Pose;

    /// A module whose `vl_step` body is `step` (leaving an i32), with the
    /// observation at 0 and the command at 256.
    fn module(step: &str) -> String {
        format!(
            r#"(module
                 (import "env" "vl_log" (func $log (param i32 i32)))
                 (memory (export "memory") 1)
                 (data (i32.const 512) "hello")
                 (func (export "vl_abi") (result i32) i32.const 1)
                 (func (export "vl_observation") (result i32) i32.const 0)
                 (func (export "vl_command") (result i32) i32.const 256)
                 (func (export "vl_step") (result i32) {step}))"#
        )
    }

    fn seen(t_s: f64) -> Observation {
        Observation {
            t_s,
            pose: Pose::default(),
            uncertainty_mm: 0.0,
            wheels: WheelSpeeds::default(),
            goal: None,
            proximity: [0.0; 8],
            period_s: 0.02,
            speed_limit_mm_s: 100.0,
        }
    }

    fn first_step(step: &str) -> Result<Answer, ControllerFault> {
        let module = Module::load(module(step).as_bytes()).unwrap();
        module.start(Budget::TWIN).unwrap().step(&seen(0.0))
    }

    #[test]
    fn a_step_reads_the_observation_and_writes_the_command() {
        // left = x, right = the speed limit; finished when t > 1.
        let step = "(f64.store (i32.const 256) (f64.load (i32.const 8)))
                    (f64.store (i32.const 264) (f64.load (i32.const 144)))
                    (f64.gt (f64.load (i32.const 0)) (f64.const 1))";
        let module_text = module(step);
        let module = Module::load(module_text.as_bytes()).unwrap();
        let mut running = module.start(Budget::TWIN).unwrap();
        let mut o = seen(0.5);
        o.pose.x_mm = 42.0;
        let answer = running.step(&o).unwrap();
        assert_eq!(
            (answer.wheels.left_mm_s, answer.wheels.right_mm_s),
            (42.0, 100.0)
        );
        assert!(!answer.finished);
        assert!(running.step(&seen(2.0)).unwrap().finished);
        assert!(running.fuel_used() > 0 && running.fuel_used() < 100);
        assert_eq!(module.hash(), ModuleHash::of(module_text.as_bytes()));
    }

    #[test]
    fn hostile_steps_end_with_their_reason() {
        let budget = Budget::TWIN.fuel_per_step;
        assert_eq!(
            first_step("(loop $l (br $l)) i32.const 0"),
            Err(ControllerFault::OutOfFuel { budget })
        );
        let trapped = first_step("unreachable");
        assert!(
            matches!(&trapped, Err(ControllerFault::Trapped(why)) if why.contains("unreachable")),
            "{trapped:?}"
        );
        let grown = first_step("(loop $l (drop (memory.grow (i32.const 16))) (br $l)) i32.const 0");
        assert_eq!(grown, Err(ControllerFault::MemoryCap { cap_mib: 16 }));
        let nan = first_step("(f64.store (i32.const 256) (f64.const nan)) i32.const 0");
        assert!(
            matches!(nan, Err(ControllerFault::NotFinite { .. })),
            "{nan:?}"
        );
        let inf = first_step("(f64.store (i32.const 264) (f64.const inf)) i32.const 0");
        assert!(
            matches!(inf, Err(ControllerFault::NotFinite { .. })),
            "{inf:?}"
        );
    }

    #[test]
    fn a_slow_step_is_late_on_the_lab_and_not_on_the_twin() {
        // Some 300,000 instructions: within the fuel, not within 1 µs.
        let step = "(local $i i32) (local.set $i (i32.const 50000))
                    (loop $l (local.set $i (i32.sub (local.get $i) (i32.const 1)))
                             (br_if $l (local.get $i))) i32.const 0";
        let step = step.replace("(local $i i32)", "");
        let body = module(&step).replace(
            "(func (export \"vl_step\") (result i32)",
            "(func (export \"vl_step\") (result i32) (local $i i32)",
        );
        let module = Module::load(body.as_bytes()).unwrap();
        let strict = Budget {
            deadline: Some(Duration::from_micros(1)),
            ..Budget::LAB
        };
        let late = module.start(strict).unwrap().step(&seen(0.0));
        assert!(
            matches!(late, Err(ControllerFault::TooSlow { .. })),
            "{late:?}"
        );
        assert!(module.start(Budget::TWIN).unwrap().step(&seen(0.0)).is_ok());
    }

    #[test]
    fn a_module_is_refused_before_it_runs() {
        let wat = module("i32.const 0");
        let refused = |bytes: &[u8]| Module::load(bytes).unwrap_err();
        assert!(matches!(
            refused(b"MZ\x90\x00 not wasm"),
            LoadError::NotWasm(_)
        ));
        assert!(matches!(
            refused(&vec![0; MAX_MODULE_BYTES + 1]),
            LoadError::TooLarge { .. }
        ));
        let system = wat.replace("\"vl_log\" (func $log", "\"system\" (func $log");
        assert_eq!(
            refused(system.as_bytes()),
            LoadError::ForbiddenImport("env.system".into())
        );
        let wrong_log = wat.replace("(param i32 i32)", "(param i32)");
        assert!(matches!(
            refused(wrong_log.as_bytes()),
            LoadError::ForbiddenImport(_)
        ));
        let memory = wat.replace(
            "(import \"env\" \"vl_log\"",
            "(import \"env\" \"mem\" (memory 1)) (import \"env\" \"vl_log\"",
        );
        assert!(matches!(
            refused(memory.as_bytes()),
            LoadError::ForbiddenImport(_)
        ));
        let no_step = wat.replace("\"vl_step\"", "\"step\"");
        assert!(matches!(
            refused(no_step.as_bytes()),
            LoadError::MissingExport {
                name: "vl_step",
                ..
            }
        ));
        let abi = wat.replace(
            "(func (export \"vl_abi\") (result i32) i32.const 1)",
            "(func (export \"vl_abi\") (result i32) i32.const 2)",
        );
        let module = Module::load(abi.as_bytes()).unwrap();
        assert_eq!(
            module.start(Budget::TWIN).unwrap_err(),
            LoadError::WrongAbi(2)
        );
        let outside = wat.replace(
            "(result i32) i32.const 256)",
            "(result i32) i32.const 65530)",
        );
        let module = Module::load(outside.as_bytes()).unwrap();
        assert!(matches!(
            module.start(Budget::TWIN).unwrap_err(),
            LoadError::OutOfMemory {
                what: "command",
                ..
            }
        ));
    }

    #[test]
    fn its_log_is_kept_within_its_rate() {
        let step = "(call $log (i32.const 512) (i32.const 5)) i32.const 0";
        let module = Module::load(module(step).as_bytes()).unwrap();
        let mut running = module.start(Budget::TWIN).unwrap();
        for i in 0..50 {
            running.step(&seen(f64::from(i) * 0.02)).unwrap();
        }
        let (lines, dropped) = running.take_log();
        assert_eq!(lines.len(), LOG_LINES_PER_S);
        assert!(lines.iter().all(|l| l == "hello"));
        assert_eq!(dropped, 40);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]

        /// Whatever a module writes as its command, a step's answer is
        /// finite speeds or a fault: nothing else reaches the wheels.
        #[test]
        fn answers_are_finite_or_a_fault(left in any::<u64>(), right in any::<u64>()) {
            let (l, r) = (f64::from_bits(left), f64::from_bits(right));
            let step = format!(
                "(i64.store (i32.const 256) (i64.const {})) (i64.store (i32.const 264) (i64.const {})) i32.const 0",
                left as i64, right as i64
            );
            match first_step(&step) {
                Ok(a) => {
                    prop_assert!(a.wheels.left_mm_s.is_finite() && a.wheels.right_mm_s.is_finite());
                    prop_assert_eq!((a.wheels.left_mm_s.to_bits(), a.wheels.right_mm_s.to_bits()), (left, right));
                }
                Err(ControllerFault::NotFinite { .. }) => prop_assert!(!l.is_finite() || !r.is_finite()),
                Err(other) => prop_assert!(false, "{}", other),
            }
        }
    }
}

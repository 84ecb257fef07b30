;; A go-to-goal controller for vl in WebAssembly's text format, interface
;; version 1 (docs/controllers.md). It turns towards the goal and drives
;; to it, slowing as it nears; it does not avoid obstacles (the lab's
;; safety layer still keeps it off them): see go_to_goal.c for one that
;; does. vl reads this file as it is; `wat2wasm` makes the binary.
(module
  (import "env" "vl_log" (func $log (param i32 i32)))
  (memory (export "memory") 1)
  ;; The observation: 32 f64 at 0 (word k at 8k). The command: 2 f64 at 256.
  (data (i32.const 512) "go to goal: starting")

  (func (export "vl_abi") (result i32) (i32.const 1))
  (func (export "vl_observation") (result i32) (i32.const 0))
  (func (export "vl_command") (result i32) (i32.const 256))

  (func (export "vl_init") (result i32)
    (call $log (i32.const 512) (i32.const 20))
    (i32.const 0))

  ;; sin x: x brought into [-pi, pi], then its Taylor series to x^11.
  (func $sin (param $x f64) (result f64)
    (local $x2 f64) (local $term f64) (local $sum f64) (local $n f64)
    (local.set $x
      (f64.sub (local.get $x)
        (f64.mul (f64.const 6.283185307179586)
          (f64.nearest (f64.div (local.get $x) (f64.const 6.283185307179586))))))
    (local.set $x2 (f64.mul (local.get $x) (local.get $x)))
    (local.set $term (local.get $x))
    (local.set $sum (local.get $x))
    (local.set $n (f64.const 1))
    (block $done
      (loop $next
        (br_if $done (f64.gt (local.get $n) (f64.const 5)))
        ;; term *= -x^2 / ((2n)(2n + 1))
        (local.set $term
          (f64.div
            (f64.mul (local.get $term) (f64.neg (local.get $x2)))
            (f64.mul
              (f64.mul (f64.const 2) (local.get $n))
              (f64.add (f64.mul (f64.const 2) (local.get $n)) (f64.const 1)))))
        (local.set $sum (f64.add (local.get $sum) (local.get $term)))
        (local.set $n (f64.add (local.get $n) (f64.const 1)))
        (br $next)))
    (local.get $sum))

  (func (export "vl_step") (result i32)
    (local $dx f64) (local $dy f64) (local $dist f64) (local $c f64) (local $s f64)
    (local $ahead f64) (local $left f64) (local $v f64) (local $w f64)
    (f64.store (i32.const 256) (f64.const 0))
    (f64.store (i32.const 264) (f64.const 0))
    ;; No goal (NaN): nothing to do.
    (if (f64.ne (f64.load (i32.const 56)) (f64.load (i32.const 56)))
      (then (return (i32.const 1))))
    (local.set $dx (f64.sub (f64.load (i32.const 56)) (f64.load (i32.const 8))))
    (local.set $dy (f64.sub (f64.load (i32.const 64)) (f64.load (i32.const 16))))
    (local.set $dist
      (f64.sqrt (f64.add (f64.mul (local.get $dx) (local.get $dx))
                         (f64.mul (local.get $dy) (local.get $dy)))))
    ;; Within 10 mm: there.
    (if (f64.lt (local.get $dist) (f64.const 10)) (then (return (i32.const 1))))
    ;; The goal's direction in the robot's frame.
    (local.set $s (call $sin (f64.load (i32.const 24))))
    (local.set $c (call $sin (f64.add (f64.load (i32.const 24)) (f64.const 1.5707963267948966))))
    (local.set $ahead
      (f64.div (f64.add (f64.mul (local.get $c) (local.get $dx))
                        (f64.mul (local.get $s) (local.get $dy)))
               (local.get $dist)))
    (local.set $left
      (f64.div (f64.sub (f64.mul (local.get $c) (local.get $dy))
                        (f64.mul (local.get $s) (local.get $dx)))
               (local.get $dist)))
    ;; Forward: 120 mm/s (or the lab's limit), less near the goal, none
    ;; while the goal is behind.
    (local.set $v
      (f64.mul
        (f64.min (f64.min (f64.const 120) (f64.load (i32.const 144)))
                 (f64.add (f64.mul (f64.const 2) (local.get $dist)) (f64.const 20)))
        (f64.max (local.get $ahead) (f64.const 0))))
    ;; Turning, rad/s: towards the goal, on the spot while it is behind.
    (local.set $w (f64.mul (f64.const 3) (local.get $left)))
    (if (f64.lt (local.get $ahead) (f64.const 0))
      (then (local.set $w (f64.add (local.get $w) (f64.copysign (f64.const 2) (local.get $left))))))
    ;; The wheels, 53 mm apart.
    (f64.store (i32.const 256) (f64.sub (local.get $v) (f64.mul (local.get $w) (f64.const 26.5))))
    (f64.store (i32.const 264) (f64.add (local.get $v) (f64.mul (local.get $w) (f64.const 26.5))))
    (i32.const 0)))

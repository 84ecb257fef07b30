// vl protocol v1 as the web Guest speaks it (docs/protocol.md): every
// message the page sends is built here and nowhere else, so a test can
// check each against the Host's types; and the camera's geometry
// (crates/vl-core/src/model/camera.rs, lens.rs), so the page draws the
// robot and the path where the Host's camera sees them.
"use strict";

const VL = (() => {
  const PROTOCOL = 1;

  // What the page sends, by kind.
  const guest = {
    // `login`: the lab's token, an account's user and password, or the
    // session an LMS launch opened.
    hello: (role, login, resume) => {
      const m = { type: "hello", protocol: PROTOCOL, role };
      if (login.session) m.session = login.session;
      if (login.token) m.token = login.token;
      if (login.user) { m.user = login.user; m.password = login.password || ""; }
      if (resume) m.resume = resume;
      return m;
    },
    ping: (t) => ({ type: "ping", t }),
    pong: (t) => ({ type: "pong", t }),
    mount: (experiment) => ({ type: "mount", experiment }),
    // `through`: the waypoints before the goal, for an experiment that
    // visits them.
    plan: (goal, through) => {
      const m = { type: "plan", goal: point(goal) };
      if (through && through.length) m.through = through.map(point);
      return m;
    },
    // `controller`: the SHA-256 of the user's own controller, taken by
    // the Host, for an experiment whose run it drives.
    define: (goal, path, waypoints, controller) => {
      const m = {
        type: "define",
        goal: { x_mm: goal.x_mm, y_mm: goal.y_mm, tolerance_mm: 15.0 },
        path: path.map(point),
      };
      if (waypoints && waypoints.length) m.waypoints = waypoints.map(point);
      if (controller) m.controller = controller;
      return m;
    },
    // The user's own controller, a file's bytes (a Uint8Array), in parts
    // of 512 KiB, each within a message.
    controller: (bytes) => {
      const PART = 512 * 1024;
      const parts = [];
      for (let offset = 0; offset < bytes.length; offset += PART) {
        const part = bytes.subarray(offset, offset + PART);
        let binary = "";
        for (let i = 0; i < part.length; i += 0x8000) {
          binary += String.fromCharCode.apply(null, part.subarray(i, i + 0x8000));
        }
        parts.push({ type: "controller", offset, total: bytes.length, data: btoa(binary) });
      }
      return parts;
    },
    start: () => ({ type: "start" }),
    stop: () => ({ type: "stop" }),
    emergency_stop: () => ({ type: "emergency_stop" }),
    command: (event, seen, v, w) => ({ type: "command", event, seen, v, w }),
    queue: () => ({ type: "queue" }),
    leave_queue: () => ({ type: "leave_queue" }),
    reset: () => ({ type: "reset" }),
    bye: () => ({ type: "bye" }),
  };

  function point(p) {
    return { x_mm: p.x_mm, y_mm: p.y_mm };
  }

  // One message of every kind the page sends, for the tests.
  function examples() {
    const goal = { x_mm: 680.0, y_mm: 470.0 };
    return [
      guest.hello("operator", { token: "lab-secret" }, null),
      guest.hello("observer", { user: "ada", password: "correct horse" }, null),
      guest.ping(1.5),
      guest.pong(2.5),
      guest.mount("navigation"),
      guest.plan(goal),
      guest.plan(goal, [{ x_mm: 300.0, y_mm: 200.0 }]),
      guest.define(goal, [{ x_mm: 100.0, y_mm: 120.0 }, goal]),
      guest.define(goal, [{ x_mm: 100.0, y_mm: 120.0 }, goal], [{ x_mm: 300.0, y_mm: 200.0 }, goal]),
      guest.define(goal, [], [], "ab".repeat(32)),
      ...guest.controller(new TextEncoder().encode("(module)")),
      guest.start(),
      guest.stop(),
      guest.emergency_stop(),
      guest.command(1, 0, 120.0, -0.5),
      guest.queue(),
      guest.leave_queue(),
      guest.reset(),
      guest.bye(),
    ];
  }

  // A camera frame: the 36-byte VLF1 header, then the image.
  const FRAME_HEADER = 36;
  function frame(buffer) {
    if (buffer.byteLength < FRAME_HEADER) return null;
    const view = new DataView(buffer);
    const magic = String.fromCharCode(
      view.getUint8(0), view.getUint8(1), view.getUint8(2), view.getUint8(3));
    if (magic !== "VLF1") return null;
    const format = view.getUint8(4);
    return {
      mime: format === 2 ? "image/png" : "image/jpeg",
      width: view.getUint16(8, true),
      height: view.getUint16(10, true),
      seq: Number(view.getBigUint64(12, true)),
      event: Number(view.getBigUint64(20, true)),
      captureMs: Number(view.getBigUint64(28, true)) / 1000,
      image: new Blob([new Uint8Array(buffer, FRAME_HEADER)], {
        type: format === 2 ? "image/png" : "image/jpeg",
      }),
    };
  }

  // The camera model's homography (mm → px) and its inverse.
  function apply(h, x, y) {
    const w = h[2][0] * x + h[2][1] * y + h[2][2];
    return [(h[0][0] * x + h[0][1] * y + h[0][2]) / w,
            (h[1][0] * x + h[1][1] * y + h[1][2]) / w];
  }

  function invert(h) {
    const [[a, b, c], [d, e, f], [g, i, k]] = h;
    const A = e * k - f * i, B = -(d * k - f * g), C = d * i - e * g;
    const det = a * A + b * B + c * C;
    return [
      [A / det, -(b * k - c * i) / det, (b * f - c * e) / det],
      [B / det, (a * k - c * g) / det, -(a * f - c * d) / det],
      [C / det, -(a * i - b * g) / det, (a * e - b * d) / det],
    ];
  }

  // The lens: radial terms, radii in image widths from the image's centre.
  function lens(camera) {
    const d = camera.distortion || { k1: 0, k2: 0 };
    const cx = camera.width_px / 2, cy = camera.height_px / 2;
    const f = Math.max(camera.width_px, 1);
    const factor = (r2) => 1 + d.k1 * r2 + d.k2 * r2 * r2;
    return {
      distort(c, r) {
        const x = (c - cx) / f, y = (r - cy) / f;
        const k = factor(x * x + y * y);
        return [cx + f * x * k, cy + f * y * k];
      },
      undistort(c, r) {
        const x = (c - cx) / f, y = (r - cy) / f;
        const seen = Math.hypot(x, y);
        if (seen < 1e-12) return [c, r];
        let u = seen;
        for (let n = 0; n < 8; n++) {
          const u2 = u * u;
          const g = u * factor(u2) - seen;
          const slope = 1 + 3 * d.k1 * u2 + 5 * d.k2 * u2 * u2;
          if (Math.abs(slope) < 1e-9) break;
          const step = g / slope;
          u -= step;
          if (Math.abs(step) < 1e-12) break;
        }
        const s = u / seen;
        return [cx + f * x * s, cy + f * y * s];
      },
    };
  }

  // Floor (mm) → image pixel, and back.
  function toPixel(camera, p) {
    const [c, r] = apply(camera.floor_to_image, p.x_mm, p.y_mm);
    return lens(camera).distort(c, r);
  }

  function toArena(camera, c, r) {
    const [uc, ur] = lens(camera).undistort(c, r);
    const [x_mm, y_mm] = apply(invert(camera.floor_to_image), uc, ur);
    return { x_mm, y_mm };
  }

  return { PROTOCOL, guest, examples, frame, toPixel, toArena };
})();

// What Foxglove's own libraries make of vl, from outside vl: every message
// of a live Host (through @foxglove/ws-protocol's client) or of a recording
// (through @mcap/core) validated against the official Foxglove schemas
// (@foxglove/schemas, with ajv); vl's own channels against the schemas they
// advertise. Prints one JSON report on stdout.
//
//   node check.mjs live URL SECONDS [drive USER PASSWORD | intrude]
//   node check.mjs mcap FILE
//   node check.mjs hello URL COUNT      (COUNT clients at once: who got serverInfo)

import { readFileSync } from "node:fs";
import wsProtocol from "@foxglove/ws-protocol";
import official from "@foxglove/schemas/jsonschema.js";
import { McapStreamReader } from "@mcap/core";
import AjvModule from "ajv";

const Ajv = AjvModule.default ?? AjvModule;
import { decompress } from "fzstd";
import WebSocket from "ws";

const { FoxgloveClient } = wsProtocol;

const ajv = new Ajv({ strict: false, validateFormats: false });
const validators = new Map();

/// The validator of a channel: Foxglove's own schema for foxglove.*, else
/// the schema the channel came with.
function validatorFor(schemaName, schemaText) {
  const key = `${schemaName}\u0000${schemaText}`;
  if (!validators.has(key)) {
    let schema;
    if (schemaName.startsWith("foxglove.")) {
      schema = official[schemaName.slice("foxglove.".length)];
      if (!schema) throw new Error(`no official schema named ${schemaName}`);
    } else {
      schema = JSON.parse(schemaText);
    }
    validators.set(key, ajv.compile(schema));
  }
  return validators.get(key);
}

/// Why Foxglove's (and Lichtblick's) JSON Schema parser would refuse a
/// channel's schema, by its rules (packages/mcap-support parseJsonSchema):
/// an object whose every property has one type of boolean, string, number,
/// integer, object or array of one of those but arrays, or is a oneOf of
/// numeric constants. Null when it reads it.
function unreadable(schema, path = "") {
  if (schema.type !== "object") return `${path || "the root"}: "type" is ${JSON.stringify(schema.type)}, not "object"`;
  for (const [name, field] of Object.entries(schema.properties ?? {})) {
    const at = path ? `${path}.${name}` : name;
    if (Array.isArray(field.oneOf)) {
      if (field.oneOf.every((c) => typeof c.const === "number")) continue;
      return `${at}: oneOf alternatives must have number values`;
    }
    if (["boolean", "string", "number", "integer"].includes(field.type)) continue;
    if (field.type === "object") {
      const why = unreadable(field, at);
      if (why) return why;
      continue;
    }
    if (field.type === "array") {
      const items = field.items ?? {};
      if (["boolean", "string", "number", "integer"].includes(items.type)) continue;
      if (items.type === "object") {
        const why = unreadable(items, at);
        if (why) return why;
        continue;
      }
      return `${at}: unsupported array item type ${JSON.stringify(items.type)}`;
    }
    return `${at}: unsupported type ${JSON.stringify(field.type)}`;
  }
  return null;
}

class Report {
  constructor() {
    this.counts = {};
    this.channels = {};
    this.bad = [];
    this.unreadable = [];
    this.channels_checked = {};
    this.latest = {};
  }
  take(topic, schemaName, schemaText, bytes) {
    this.counts[topic] = (this.counts[topic] ?? 0) + 1;
    this.channels[topic] = schemaName;
    let message;
    try {
      message = JSON.parse(new TextDecoder().decode(bytes));
    } catch (e) {
      this.bad.push({ topic, error: `not JSON: ${e}` });
      return;
    }
    if (!(topic in this.channels_checked)) {
      this.channels_checked[topic] = true;
      const why = unreadable(JSON.parse(schemaText));
      if (why) this.unreadable.push({ topic, schema: schemaName, why });
    }
    const validate = validatorFor(schemaName, schemaText);
    if (!validate(message) && this.bad.length < 20) {
      this.bad.push({ topic, schema: schemaName, errors: validate.errors.slice(0, 3) });
    }
    this.latest[topic] = message;
    if (topic === "/robot/motion" && typeof message.tracking_error_mm === "number") {
      this.tracked = (this.tracked ?? 0) + 1;
    }
    if (topic === "/robot/pose") {
      const { x, y } = message.pose.position;
      this.first_pose ??= { x, y };
      const d = Math.hypot(x - this.first_pose.x, y - this.first_pose.y);
      this.farthest_mm = Math.max(this.farthest_mm ?? 0, d * 1000);
    }
  }
}

/// A few numbers of the newest messages, to show what the panels would.
function summary(report) {
  const l = report.latest;
  const grid = l["/map"];
  return {
    map: grid && { columns: grid.column_count, bytes: Buffer.from(grid.data, "base64").length },
    cspace_cells: l["/cspace"] && Buffer.from(l["/cspace"].data, "base64").length,
    calibration: l["/camera/calibration"] && { K: l["/camera/calibration"].K, width: l["/camera/calibration"].width },
    camera_at: l["/tf_static"] && l["/tf_static"].translation,
    pose: l["/robot/pose"] && l["/robot/pose"].pose.position,
    motion: l["/robot/motion"],
    path_poses: l["/path"] && l["/path"].poses.length,
    scene_entities: l["/scene"] && l["/scene"].entities.map((e) => e.id),
  };
}

async function live(url, seconds, mode, user, password) {
  const ws = new WebSocket(url, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]);
  const client = new FoxgloveClient({ ws });
  const report = new Report();
  const bySubscription = new Map();
  const statuses = [];
  const responses = [];
  const out = { subprotocol: null, serverInfo: null, statuses, responses, times: 0, close: null, latched_first: {} };
  let services = [];
  let started = Date.now();
  client.on("open", () => (out.subprotocol = ws.protocol));
  client.on("serverInfo", (info) => (out.serverInfo = info));
  client.on("status", (s) => statuses.push(s));
  client.on("time", () => (out.times += 1));
  client.on("advertise", (channels) => {
    for (const channel of channels) {
      const id = client.subscribe(channel.id);
      bySubscription.set(id, channel);
    }
  });
  client.on("advertiseServices", (s) => (services = s));
  client.on("serviceCallResponse", (r) =>
    responses.push({ serviceId: r.serviceId, data: JSON.parse(new TextDecoder().decode(r.data)) }),
  );
  client.on("serviceCallFailure", (f) => responses.push({ serviceId: f.serviceId, failure: f.message }));
  client.on("message", ({ subscriptionId, data }) => {
    const channel = bySubscription.get(subscriptionId);
    if (!channel) return;
    if (!(channel.topic in out.latched_first)) out.latched_first[channel.topic] = Date.now() - started;
    report.take(channel.topic, channel.schemaName, channel.schema, new Uint8Array(data.buffer, data.byteOffset, data.byteLength));
  });
  const closed = new Promise((resolve) => ws.on("close", (code) => resolve(code)));
  await new Promise((resolve, reject) => {
    ws.on("open", resolve);
    ws.on("error", reject);
  });
  started = Date.now();
  const call = (name, request) => {
    const service = services.find((s) => s.name === name);
    if (!service) throw new Error(`no service ${name}`);
    client.sendServiceCallRequest({
      serviceId: service.id,
      callId: responses.length + statuses.length,
      encoding: "json",
      data: new TextEncoder().encode(JSON.stringify(request)),
    });
  };
  const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
  if (mode === "drive" || mode === "intrude") {
    await sleep(500);
    const cmdVel = client.advertise({ topic: "/cmd_vel", encoding: "json", schemaName: "geometry_msgs/Twist" });
    if (mode === "drive") {
      call("/vl/control", user ? { user, password } : {});
      await sleep(500);
      call("/vl/mount", { experiment: "teleoperation" });
      await sleep(500);
      call("/vl/start", {});
      await sleep(500);
    }
    const twist = new TextEncoder().encode(
      JSON.stringify({ linear: { x: 0.06, y: 0, z: 0 }, angular: { x: 0, y: 0, z: 0 } }),
    );
    const until = Date.now() + seconds * 1000;
    while (Date.now() < until) {
      client.sendMessage(cmdVel, twist);
      await sleep(50);
    }
    if (mode === "drive") call("/vl/stop", {});
    await sleep(300);
  } else {
    await sleep(seconds * 1000);
  }
  // A close with a code, which the server's answer echoes (RFC 6455).
  ws.close(1000, "done");
  out.close = await Promise.race([closed, sleep(3000).then(() => "no close")]);
  Object.assign(out, report, { summary: summary(report) });
  delete out.latest;
  delete out.channels_checked;
  return out;
}

function mcap(file) {
  const reader = new McapStreamReader({
    decompressHandlers: { zstd: (buffer, size) => decompress(buffer, new Uint8Array(Number(size))) },
  });
  reader.append(readFileSync(file));
  const schemas = new Map();
  const channels = new Map();
  const report = new Report();
  for (let record; (record = reader.nextRecord()); ) {
    if (record.type === "Schema") schemas.set(record.id, record);
    else if (record.type === "Channel") channels.set(record.id, record);
    else if (record.type === "Message") {
      const channel = channels.get(record.channelId);
      const schema = schemas.get(channel.schemaId);
      report.take(channel.topic, schema.name, new TextDecoder().decode(schema.data), record.data);
    }
  }
  const out = { ...report, summary: summary(report) };
  delete out.latest;
  delete out.channels_checked;
  return out;
}

async function hello(url, count) {
  const one = () =>
    new Promise((resolve) => {
      const ws = new WebSocket(url, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]);
      const client = new FoxgloveClient({ ws });
      const timer = setTimeout(() => (ws.terminate(), resolve(false)), 10000);
      client.on("serverInfo", (info) => {
        clearTimeout(timer);
        client.close();
        resolve(info.sessionId);
      });
      ws.on("error", () => (clearTimeout(timer), resolve(false)));
    });
  const sessions = await Promise.all(Array.from({ length: count }, one));
  return { got: sessions.filter(Boolean).length, sessions: [...new Set(sessions)] };
}

const [mode, target, arg, extra, user, password] = process.argv.slice(2);
let result;
if (mode === "live") result = await live(target, Number(arg), extra, user, password);
else if (mode === "mcap") result = mcap(target);
else if (mode === "hello") result = await hello(target, Number(arg));
else throw new Error(`usage: check.mjs live|mcap|hello …, not ${mode}`);
process.stdout.write(JSON.stringify(result) + "\n");
process.exit(0);

// The page: one store of what the wire said, fed live by the WebSocket or by a recording
// (replay), and panels drawn from the store. Views come from services/web/views.py (hands are
// already in the robot base frame, high-rate streams already downsampled).
import { colourOf, lines, spans, strip } from "./charts.js";
import { SceneView } from "./scene.js";

const WINDOW_S = 10;        // the gesture charts' time window
const EPISODE_WINDOW_S = 60;  // the episode strip's shortest time span
const EPISODES_SHOWN = 6;   // the newest episodes, in the table and on the strip alike
const $ = (id) => document.getElementById(id);
const esc = (v) => String(v ?? "").replace(/[&<>"']/g, (c) => `&#${c.charCodeAt(0)};`);
const pct = (p) => `${(100 * p).toFixed(0)}%`;
const xyz = (p) => p ? `(${p.map((v) => v.toFixed(2)).join(", ")})` : "—";
// A number for people: integers as they are, others to three significant digits
// (0.09201324545581968 -> 0.092, 89.52360539551889 -> 89.5).
const num = (v) => typeof v !== "number" || Number.isInteger(v) ? String(v) : String(Number(v.toPrecision(3)));
const paramsText = (params) => Object.entries(params || {}).map(([k, v]) => `${k} ${num(v)}`).join(", ") || "—";
// An intent the intent service did not accept names no action: it is shown as refused, with
// its status and reason, never as an empty call "()".
const refused = (i) => i.status !== "accepted";
const call = (i) => `${i.action ?? "—"}(${i.object ?? ""})`;

function emptyStore() {
  return { hands: null, scene: null, intentScene: null, robot: null, gaze: null, user: null, plan: null,
    intent: null, services: null, stop: null, staticP: [], dynamicP: [], evidence: [],
    clarify: null, mapping: null, preview: null, events: [], summaries: [], intents: [], feedback: [], now: 0,
    dirty: new Set(["all"]) };
}

let store = emptyStore();
let info = { mode: "live", actions: [] };
let workspace = null;
let socket = null, nextId = 1, live = true;
const pending = new Map();
const dismissed = new Set();
let sceneView = null;

// --------------------------------------------------------------------- the store

function stamp(msg, t) { return typeof msg.ts === "number" ? msg.ts : t; }

function keepRecent(list, now, seconds) {
  while (list.length && list[0].ts < now - seconds) list.shift();
}

function apply(topic, msg, t) {
  const ts = stamp(msg, t);
  if (topic[0] !== "@") store.now = Math.max(store.now, ts);
  const handlers = {
    "hands/frame": () => { store.hands = msg; },
    "gaze": () => { store.gaze = msg; },
    "camera/preview": () => { store.preview = msg; },
    "user": () => { store.user = msg.user; },
    "scene/state": () => { store.scene = msg; },
    "robot/state": () => { store.robot = msg; },
    "plan/status": () => { store.plan = msg; },
    "robot/stop": () => { store.stop = { ts, reason: msg.reason }; },
    "intent/feedback": () => { store.feedback.push(msg); store.feedback = store.feedback.slice(-10); },
    "intent/clarify": () => { store.clarify = msg; },
    // The scene the intent was inferred on: the why-line measures against it, not against a
    // world the plan has changed since (a picked-up cup is no longer where the user looked).
    "intent": () => { store.intent = msg; store.intentScene = store.scene; store.intents.push(msg); store.intents = store.intents.slice(-20); },
    "gestures/static": () => store.staticP.push(msg),
    "gestures/dynamic": () => store.dynamicP.push(msg),
    "@evidence": () => store.evidence.push(msg),
    "episode/event": () => { store.events.push(msg); store.events = store.events.slice(-300); },
    "episode/summary": () => { store.summaries.push(msg); store.summaries = store.summaries.slice(-30); },
    "@services": () => { store.services = msg; },
    "@workspace": () => { workspace = msg; sceneView?.setWorkspace(msg.workspace); },
    "@reply": () => answered(msg),
    "@mapping": () => mappingAnswered(msg),
  };
  (handlers[topic] || (() => {}))();
  store.dirty.add(topic);
}

function trim() {
  for (const list of [store.staticP, store.dynamicP, store.evidence]) keepRecent(list, store.now, WINDOW_S + 1);
}

// --------------------------------------------------------------------- panels

function summaryOf(episode) { return store.summaries.find((s) => s.episode === episode); }

function top(map, n) { return Object.entries(map || {}).sort((a, b) => b[1] - a[1]).slice(0, n); }

function bars(map, cls) {
  return `<div class="bars">${top(map, 5).map(([name, p]) =>
    `<span>${esc(name)}</span><div class="bar ${cls}" style="width:${(100 * p).toFixed(1)}%"></div><span>${pct(p)}</span>`).join("")}</div>`;
}

function distance(a, b) { return Math.hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]); }

// Why this object: the focus's distance to it (and to the runner-up), the gesture, the user.
function whyLine(intent) {
  const summary = summaryOf(intent.episode);
  if (!summary) return "the episode's summary was not seen";
  const [gesture, gp] = top(Object.fromEntries(summary.gestures.names.map((n, i) => [n, summary.gestures.probs[i]])), 1)[0] || ["none", 0];
  const parts = [];
  const objects = (store.intentScene || store.scene)?.objects || [];
  const chosen = objects.find((o) => o.name === intent.object);
  if (summary.focus && chosen) {
    parts.push(`focus (${summary.focus_source}) ${distance(summary.focus, chosen.position).toFixed(2)} m from ${esc(chosen.name)}`);
    const others = objects.filter((o) => o !== chosen).map((o) => [o.name, distance(summary.focus, o.position)]).sort((a, b) => a[1] - b[1]);
    if (others.length) parts.push(`next nearest ${esc(others[0][0])} at ${others[0][1].toFixed(2)} m`);
  } else if (!summary.focus) {
    parts.push("no focus: the user looked at nothing");
  }
  parts.push(`gesture ${esc(gesture)} ${pct(gp)}`, `user ${esc(summary.user)}`);
  return parts.join(" · ");
}

function reasonInWords(intent) {
  if (intent.reason) return intent.reason;
  return { accepted: `accepted with confidence ${pct(intent.confidence)}`,
    low_confidence: `not acted on: confidence ${pct(intent.confidence)} is too low`,
    infeasible: "not possible in this scene" }[intent.status] || intent.status;
}

function placeholder(id, text) {
  $(id).className = "muted"; $(id).textContent = text;
}

function drawIntent() {
  const i = store.intent;
  if (!i) return placeholder("intent-body", "no intent yet");
  $("intent-body").className = "";
  $("intent-body").innerHTML = `
    <div><span class="big${refused(i) ? " refused" : ""}">${refused(i) ? "refused" : esc(call(i))}</span><span class="status ${esc(i.status)}">${esc(i.status)}</span></div>
    <div class="muted">episode ${esc(i.episode ?? "—")} · model ${esc(i.model)} · confidence ${pct(i.confidence)}</div>
    <div class="why"><b>reason:</b> ${esc(reasonInWords(i))}</div>
    ${i.object ? `<div class="why"><b>why this object:</b> ${whyLine(i)}</div>` : ""}
    ${Object.keys(i.p_action || {}).length ? `<div class="muted">p(action)</div>${bars(i.p_action, "")}` : ""}
    ${Object.keys(i.p_object || {}).length ? `<div class="muted">p(object)</div>${bars(i.p_object, "obj")}` : ""}`;
}

function drawPlan() {
  const p = store.plan;
  if (!p) placeholder("plan-body", "no plan yet");
  else {
    const i = p.intent;
    $("plan-body").className = "";
    $("plan-body").innerHTML = `
      <div><b>${esc(call(i))}</b><span class="status ${esc(p.state)}">${esc(p.state)}</span></div>
      <ol class="steps">${p.sequence.map((s) => `<li>${esc(s.action)}(${esc(s.object ?? "")})
        <span class="status ${esc(s.state)}">${esc(s.state)}</span></li>`).join("")}</ol>
      ${p.error ? `<div class="err">${esc(p.error)}</div>` : ""}`;
  }
  const r = store.robot, held = store.scene?.robot?.holding;
  if (!r && !store.scene) placeholder("robot-body", "");
  else {
    $("robot-body").className = "mono";
    $("robot-body").innerHTML = `robot: TCP ${xyz(r?.tcp || store.scene?.robot?.tcp)}` +
      (r ? ` · gripper ${(r.gripper_width * 1000).toFixed(0)} mm · ${r.moving ? "moving" : "still"}` +
        (r.action ? ` · doing ${esc(r.action)}` : "") : "") +
      ` · holding ${esc(held ?? "nothing")}` + worldLine() +
      (store.stop ? `<div class="err">last stop: ${new Date(store.stop.ts * 1000).toLocaleTimeString()} ${esc(store.stop.reason ?? "")}</div>` : "");
  }
}

// Where the robot's world comes from, so that a start scene with a held cup or an open drawer
// reads as the robot's own start, not as something that happened: the robot cell's status
// (scene_source, actions) as the services poll brought it.
function worldLine() {
  const cell = store.services?.services.find((r) => r.scene_source);
  if (!cell) return "";
  const scene = cell.scene_source === "scene" ? "scene from a file or a reset" : `scene of ${cell.scene_source}`;
  const done = cell.actions ? `${cell.actions} action${cell.actions === 1 ? "" : "s"}` : "no action";
  return `<div class="muted" data-testid="world-source" title="cbgo sim reset --seed N or --scene FILE loads another">world: ${esc(cell.name)}'s ${esc(scene)} · ${done} since it started</div>`;
}

// One line per gesture, and per hand when both hands are seen.
function seriesOf(messages) {
  const series = new Map();
  const both = new Set(messages.map((m) => m.side)).size > 1;
  for (const m of messages) {
    m.names.forEach((name, k) => {
      if (name === "none" || name === "no_gesture") return;
      const key = both ? `${name} ${m.side[0]}` : name;
      if (!series.has(key)) series.set(key, []);
      series.get(key).push([m.ts, m.probs[k]]);
    });
  }
  return series;
}

function drawGestures() {
  const t1 = store.now || Date.now() / 1000, t0 = t1 - WINDOW_S;
  const triggers = store.events.filter((e) => e.kind === "trigger" && e.ts >= t0);
  const bounds = store.events.filter((e) => e.kind !== "trigger" && e.ts >= t0);
  const markers = [...triggers.map((e) => ({ t: e.ts, label: `${e.gesture} ${pct(e.prob)}` })),
    ...bounds.map((e) => ({ t: e.ts, label: e.kind, colour: "#8893a2" }))];
  lines($("chart-static"), seriesOf(store.staticP), t0, t1, { markers, empty: "no static gestures (no hand?)" });
  const windows = [];
  for (const m of store.dynamicP) m.names.forEach((name, k) => windows.push({ t0: m.window[0], t1: m.window[1], name, v: m.probs[k] }));
  spans($("chart-dynamic"), windows.filter((w) => w.t1 >= t0 && !w.name.startsWith("no")), t0, t1,
    { empty: "no dynamic window" });
  const evidence = new Map();
  let threshold;
  for (const e of store.evidence) {
    threshold = e.threshold;
    for (const [name, v] of Object.entries(e.values)) {
      if (!evidence.has(name)) evidence.set(name, []);
      evidence.get(name).push([e.ts, v]);
    }
  }
  lines($("chart-evidence"), evidence, t0, t1, { threshold: threshold ?? 0.6, markers: triggers.map((e) => ({ t: e.ts, label: e.gesture })), empty: "no evidence" });
  $("triggers").innerHTML = triggers.length ? "triggers: " + triggers.map((e) =>
    `<span style="color:${colourOf(e.gesture)}">${esc(e.gesture)} ${pct(e.prob)}</span>`).join(", ") : "no trigger in this window";
  $("window-s").textContent = WINDOW_S;
}

// The newest episodes, oldest first: start, end (null while open) and summary once published.
// The table and the strip show exactly these, so they always count the same episodes. An
// episode whose end was never seen counts only while it is the newest (the one under way).
function recentEpisodes() {
  const byName = new Map();
  const of = (name) => {
    if (!byName.has(name)) byName.set(name, { name, t0: null, t1: null, summary: null });
    return byName.get(name);
  };
  for (const e of store.events) {
    if (e.kind === "start") of(e.episode).t0 = e.ts;
    if (e.kind === "end") of(e.episode).t1 = e.ts;
  }
  for (const s of store.summaries) {
    const ep = of(s.episode);
    ep.summary = s; ep.t0 ??= s.started; ep.t1 ??= s.ended;
  }
  const all = [...byName.values()].filter((ep) => ep.t0 !== null).sort((a, b) => a.t0 - b.t0);
  return all.filter((ep, k) => ep.t1 !== null || k === all.length - 1).slice(-EPISODES_SHOWN);
}

function leader(s) {
  const k = s.gestures.probs.indexOf(Math.max(...s.gestures.probs));
  return k >= 0 ? `${s.gestures.names[k]} ${pct(s.gestures.probs[k])}` : "—";
}

function intentCell(intent) {
  if (!intent) return "—";
  if (!refused(intent)) return `${esc(call(intent))} <span class="status ${esc(intent.status)}">${esc(intent.status)}</span>`;
  return `<span class="refused">refused</span> <span class="status ${esc(intent.status)}">${esc(intent.status)}</span>
    <div class="muted reason">${esc(intent.reason || reasonInWords(intent))}</div>`;
}

function episodeRow(ep) {
  const s = ep.summary;
  if (!s) return `<tr data-episode="${esc(ep.name)}"><td class="mono">${esc(ep.name.slice(-9))}</td>
    <td colspan="7" class="muted">${ep.t1 === null ? "under way" : "ended; its summary was not seen"}</td></tr>`;
  const g = s.gestures.names.map((n, i) => [n, s.gestures.probs[i]]).sort((a, b) => b[1] - a[1]).slice(0, 3);
  const intent = store.intents.findLast((i) => i.episode === s.episode);
  return `<tr data-episode="${esc(ep.name)}"><td class="mono">${esc(s.episode.slice(-9))}</td><td>${esc(s.user)}</td>
    <td>${(s.ended - s.started).toFixed(2)} s</td>
    <td>${g.map(([n, p]) => `${esc(n)} ${p.toFixed(2)}`).join(", ")}</td>
    <td class="mono">${xyz(s.focus)} ${esc(s.focus_source ?? "")}</td>
    <td class="mono">${esc(paramsText(s.params))}</td>
    <td>${s.triggers.map((t) => esc(t.gesture)).join(", ") || "—"}</td>
    <td>${intentCell(intent)}</td></tr>`;
}

function drawEpisodes() {
  const episodes = recentEpisodes();
  const t1 = store.now || Date.now() / 1000;
  const t0 = Math.min(t1 - EPISODE_WINDOW_S, (episodes[0]?.t0 ?? t1) - 1);
  strip($("chart-episodes"), episodes.map((ep) => ({ t0: ep.t0, t1: ep.t1, open: ep.t1 === null,
    label: ep.t1 === null ? "…" : ep.summary ? leader(ep.summary) : ep.name.slice(-4) })), t0, t1);
  $("chart-episodes").dataset.episodes = episodes.length;
  if (!episodes.length) return placeholder("episodes-body", "no episode yet");
  $("episodes-body").className = "";
  $("episodes-body").innerHTML = `<table><tr><th>episode</th><th>user</th><th>length</th><th>g (top 3)</th>
    <th>focus</th><th>params</th><th>triggers</th><th>intent</th></tr>${episodes.slice().reverse().map(episodeRow).join("")}</table>`;
}

// A counter in at most five characters (10932 -> 10.9k); the exact figures are in the title.
function count(n) {
  if (n < 10000) return String(n);
  return n < 1e6 ? `${Number((n / 1e3).toPrecision(3))}k` : `${Number((n / 1e6).toPrecision(3))}M`;
}

// An uptime like `cbgo status` prints it: 12s, 4m05s, 3h02m.
function uptime(seconds) {
  if (seconds == null) return "—";
  if (seconds < 60) return `${seconds.toFixed(0)}s`;
  const m = Math.floor(seconds / 60), h = Math.floor(m / 60);
  return h ? `${h}h${String(m % 60).padStart(2, "0")}m` : `${m}m${String(Math.floor(seconds % 60)).padStart(2, "0")}s`;
}

// One row per service; its last error, when it has one, on a row of its own below, across the
// table, so that it wraps instead of being cut off. `oneHost`: every service runs on it (the
// header names it once instead of each row).
function serviceRows(r, oneHost) {
  const c = r.counters;
  const where = oneHost ? esc(r.pid ?? "—") : `${esc(r.pid ?? "—")}<wbr>@${esc(r.host ?? "?")}`;
  const row = `<tr data-service="${esc(r.name)}"><td><span class="dot ${r.alive ? "on" : "off"}"></span>${esc(r.name)}</td>
    <td class="mono host">${where}</td>
    <td>${uptime(r.uptime_s)}</td>
    <td class="mono" title="${c ? `received ${c.received}, published ${c.published}, rejected ${c.rejected}, errors ${c.errors}` : ""}">${c ? [c.received, c.published, c.rejected, c.errors].map(count).join("/<wbr>") : "no status"}</td></tr>`;
  if (!r.last_error) return row;
  const when = r.last_error.ts ? new Date(r.last_error.ts * 1000).toLocaleTimeString() + " " : "";
  return row + `<tr class="last-error" data-error-of="${esc(r.name)}"><td colspan="4" class="err">
    last error ${esc(when)}${esc(`${r.last_error.where}: ${r.last_error.message}`.slice(0, 400))}</td></tr>`;
}

function drawServices() {
  const s = store.services;
  if (!s) return placeholder("services-body", info.mode === "live" ? "asking…" : "replay: no live services");
  const hosts = new Set(s.services.map((r) => r.host).filter(Boolean));
  const oneHost = hosts.size === 1 ? [...hosts][0] : null;
  $("services-body").className = "";
  $("services-body").innerHTML = `<table class="services"><tr><th>service</th><th>${oneHost ? `pid <span class="muted">@${esc(oneHost)}</span>` : "pid@host"}</th><th>up</th>
    <th title="received / published / rejected / errors">in/out/rej/err</th></tr>
    ${s.services.map((r) => serviceRows(r, oneHost)).join("")}</table>`;
}

// --------------------------------------------------------------------- feedback and STOP

function best(map) { return top(map, 1)[0]?.[0] ?? null; }

function drawFeedback() {
  const i = store.intent;
  if (!i) return placeholder("feedback-body", "no intent to correct yet");
  const live = info.mode === "live";
  const objects = (store.scene?.objects || []).map((o) => o.name);
  const options = (list, chosen) => list.map((v) => `<option ${v === chosen ? "selected" : ""}>${esc(v)}</option>`).join("");
  const low = i.status === "low_confidence" && !dismissed.has(i.episode);
  const guess = `${i.action ?? best(i.p_action)}(${i.object ?? best(i.p_object) ?? ""})`;
  $("feedback-body").className = "";
  $("feedback-body").innerHTML = `
    <div class="muted">episode ${esc(i.episode ?? "—")} of ${esc(summaryOf(i.episode)?.user ?? "an unknown user")}</div>
    ${low ? `<div class="why">low confidence: did you mean <b>${esc(guess)}</b>?
      <div class="row"><button id="fb-confirm" data-testid="feedback-confirm" ${live ? "" : "disabled"}>Confirm (teaches the model)</button>
      <button id="fb-reject" data-testid="feedback-reject">Reject (nothing moved; nothing is sent)</button></div></div>` : ""}
    <div class="row">I meant <select id="fb-action">${options(info.actions, i.action ?? best(i.p_action))}</select>
      on <select id="fb-object"><option value="">(no object)</option>${options(objects, i.object)}</select>
      <button id="fb-send" data-testid="feedback-send" ${live ? "" : "disabled"}>Correct</button></div>
    <div id="fb-result" class="muted">${live ? "publishes cbgo/intent/feedback: the intent service learns this user's gestures" : "replay: nothing is published"}</div>`;
  $("fb-send").onclick = () => sendFeedback($("fb-action").value, $("fb-object").value || null, i);
  if (low) {
    $("fb-confirm").onclick = () => sendFeedback(i.action ?? best(i.p_action), i.object ?? best(i.p_object), i);
    $("fb-reject").onclick = () => { dismissed.add(i.episode); store.dirty.add("intent"); };
  }
}

// --------------------------------------------------------------------- asked back

// The open clarification's highlighted candidate is the scene's target; a closed one shows
// what became of it (confirmed, expired, cancelled).
let clarifySent = null;  // the page's last answer: {id, ok, text}

function asking() { return store.clarify?.state === "open" ? store.clarify : null; }

function sceneTarget() {
  const c = asking();
  return c ? c.candidates[c.highlighted]?.object ?? null : store.intent?.object;
}

function drawClarify() {
  const c = store.clarify;
  if (!c) return placeholder("clarify-body", "no question open");
  const open = c.state === "open";
  $("clarify-body").className = "";
  const left = Math.max(0, c.expires - Date.now() / 1000);
  const sent = clarifySent?.id === c.id ? clarifySent : null;  // kept across redraws
  $("clarify-body").innerHTML = `
    <div data-testid="clarify-state">${esc(c.user)}: ${open ? `which one did you mean? (${left.toFixed(0)} s)` : esc(c.state)}
      <span class="muted">${esc(c.reason)}</span></div>
    <ol class="candidates">${c.candidates.map((k, n) => `<li>
      <button data-testid="clarify-candidate-${n}" data-n="${n}" ${open && live ? "" : "disabled"}
        class="${n === c.highlighted ? "highlighted" : ""}">${esc(k.action)}(${esc(k.object ?? "")})</button>
      ${pct(k.p)}${n === c.highlighted ? " ← thumbs-up confirms; a swipe steps" : ""}</li>`).join("")}</ol>
    <div id="clarify-result" class="${sent?.ok === false ? "err" : "muted"}">${esc(sent?.text ?? (open ? "a click confirms (publishes cbgo/intent/answer)" : ""))}</div>`;
  for (const button of $("clarify-body").querySelectorAll("button[data-n]")) {
    button.onclick = () => answerClarification(c, Number(button.dataset.n));
  }
}

function answerClarification(c, choice) {
  request({ type: "answer", clarification: c.id, user: c.user, answer: "confirm", choice }, (a) => {
    clarifySent = { id: c.id, ok: a.ok, text: a.ok ? `sent to ${a.key}: confirm ${choice}` : `not sent: ${a.error}` };
    store.dirty.add("intent/clarify");
  });
}

// --------------------------------------------------------------------- gesture mapping

// A user's own mapping, asked of the intent service (which owns the user's mapping.yaml and
// validates every rule): the table shows the rules, "set" adds or replaces one, "unset"
// removes one. The answer comes back on @mapping, to every page.
let mappingUser = null;  // whose mapping is shown: the current user until one is typed
let mappingNote = null;  // what became of the page's last mapping request: {ok, text}
let mappingDrawnFor = null;  // the user the panel was last drawn for

function askMapping(extra) {
  const user = ($("map-user")?.value ?? "").trim() || mappingUser || store.user;
  if (!user) { mappingNote = { ok: false, text: "no user yet: type a name" }; store.dirty.add("@mapping"); return; }
  mappingUser = user;
  request({ type: "mapping", user, op: "show", ...extra }, (a) => {
    mappingNote = a.ok ? { ok: true, text: `asked ${a.key}…` } : { ok: false, text: `not sent: ${a.error}` };
    store.dirty.add("@mapping");
  });
}

// The current user's mapping, asked when they first show up (the panel follows the current
// user until a name is typed); no note when it cannot be asked: "show" still can.
function followMapping() {
  if (info.mode !== "live" || mappingUser !== null || !store.user) return;
  request({ type: "mapping", user: store.user, op: "show" }, () => {});
}

function mappingAnswered(msg) {
  if (msg.user !== (mappingUser ?? store.user)) return;
  if (msg.ok) store.mapping = msg;  // a refused edit keeps the table as it was
  mappingNote = !msg.ok ? { ok: false, text: msg.error }
    : { ok: true, text: msg.op === "show" ? `from ${msg.path}` : `${msg.op}: written to ${msg.path}` };
}

function mappingState(m) {
  if (!m?.ok) return "";
  if (m.error) return `<span class="err">the file does not load (${esc(m.error)}); the mapping in use stays</span>`;
  return m.refitting ? "refitting the user's model (about 10 s)…" : "in use";
}

function drawMapping() {
  const user = mappingUser ?? store.user ?? "";  // none yet: a name can be typed
  mappingDrawnFor = store.user;
  const m = store.mapping?.ok && store.mapping.user === user ? store.mapping : null;
  const canEdit = info.mode === "live";
  const options = (list, blank) => (blank ? `<option value="">${blank}</option>` : "")
    + (list || []).map((v) => `<option>${esc(v)}</option>`).join("");
  const types = Object.keys(m?.known?.states || {});
  const states = [...new Set(Object.values(m?.known?.states || {}).flat())];
  const rows = (m?.rules || []).map((r, n) => `<tr data-testid="mapping-rule-${n}"><td>${esc(r.gesture)}</td>
    <td>${esc(r.action)}</td><td>${esc(r.on ?? "any")}</td><td>${esc(r.state ?? "either")}</td>
    <td><button data-unset="${n}" data-testid="mapping-unset-${n}" ${canEdit ? "" : "disabled"}>unset</button></td></tr>`).join("");
  $("mapping-body").className = "";
  $("mapping-body").innerHTML = `
    <div class="row">user <input id="map-user" data-testid="mapping-user" value="${esc(user)}" size="10">
      <button id="map-show" data-testid="mapping-show" ${canEdit ? "" : "disabled"}>show</button>
      <span data-testid="mapping-state">${mappingState(m)}</span></div>
    ${m ? `<table data-testid="mapping-table"><tr><th>gesture</th><th>means</th><th>on</th><th>state</th><th></th></tr>
      ${rows || `<tr><td colspan="5" class="muted">no rules: the model's default reading</td></tr>`}</table>
    <div class="row"><select id="map-gesture" data-testid="mapping-gesture">${options(m.known.gestures)}</select> means
      <select id="map-action" data-testid="mapping-action">${options(m.known.actions)}</select> on
      <select id="map-on" data-testid="mapping-on">${options(types, "any")}</select>
      <select id="map-state" data-testid="mapping-in-state">${options(states, "either")}</select>
      <button id="map-set" data-testid="mapping-set" ${canEdit ? "" : "disabled"}>set</button></div>` : ""}
    <div id="map-result" data-testid="mapping-result" class="${mappingNote?.ok === false ? "err" : "muted"}">${esc(
      mappingNote?.text ?? "asks the intent service (@ctl/intent/mapping), which writes the user's mapping.yaml")}</div>`;
  $("map-show").onclick = () => askMapping({});
  if (!m) return;
  $("map-set").onclick = () => askMapping({ op: "set", gesture: $("map-gesture").value,
    action: $("map-action").value, on: $("map-on").value || null, state: $("map-state").value || null });
  for (const button of $("mapping-body").querySelectorAll("button[data-unset]")) {
    const rule = m.rules[Number(button.dataset.unset)];
    button.onclick = () => askMapping({ op: "unset", gesture: rule.gesture, on: rule.on ?? null, state: rule.state ?? null });
  }
}

function request(body, onAnswer) {
  if (!socket || socket.readyState !== WebSocket.OPEN) {
    onAnswer({ ok: false, error: "not connected to the web service" });
    return;
  }
  const id = nextId++;
  pending.set(id, onAnswer);
  socket.send(JSON.stringify({ ...body, id }));
}

function answered(msg) {
  const onAnswer = pending.get(msg.id);
  pending.delete(msg.id);
  if (onAnswer) onAnswer(msg);
  else if (!msg.ok) console.warn("the web service refused a request:", msg.error);
}

function sendFeedback(action, object, intent) {
  // The server takes the user from the episode's summary; the current user is its fallback.
  request({ type: "feedback", action, object, episode: intent.episode, user: store.user }, (a) => {
    $("fb-result").textContent = a.ok ? `sent to ${a.key}: ${action}(${object ?? ""})` : `not sent: ${a.error}`;
    $("fb-result").className = a.ok ? "" : "err";
    if (a.ok) dismissed.add(intent.episode);
  });
}

function stop() {
  $("stop").classList.add("sent");
  setTimeout(() => $("stop").classList.remove("sent"), 400);
  if (info.mode !== "live") { $("stop-result").textContent = "replay: there is no robot to stop"; return; }
  request({ type: "stop" }, (a) => {
    $("stop-result").textContent = a.ok ? `STOP sent on ${a.key} at ${new Date().toLocaleTimeString()}`
      : `STOP NOT SENT: ${a.error}`;
    $("stop-result").className = a.ok ? "" : "err";
  });
}

// --------------------------------------------------------------------- live and replay

function connect() {
  const url = `${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws`;
  socket = new WebSocket(url);
  socket.onopen = () => {
    // Every connection starts with the server's snapshot (the histories included): start the
    // store afresh, or a reconnect would show each remembered event twice.
    store = emptyStore();
    $("link").textContent = "live"; $("link").className = "badge on";
  };
  socket.onmessage = (e) => { const m = JSON.parse(e.data); apply(m.topic, m.msg, m.t); };
  socket.onclose = () => {
    for (const [, onAnswer] of pending) onAnswer({ ok: false, error: "the connection closed" });
    pending.clear();
    if (!live) return;  // replaying an opened recording: the live stream is left on purpose
    $("link").textContent = "disconnected, retrying…"; $("link").className = "badge off";
    setTimeout(connect, 1000);
  };
}

// Opens a recording from this computer: the server reads it, the page scrubs through it.
async function openRecording(file) {
  $("open-result").textContent = `reading ${file.name}…`;
  const answer = await fetch("/api/upload", { method: "POST", body: file,
    headers: { "X-File-Name": file.name } });
  if (!answer.ok) { $("open-result").textContent = `cannot open: ${await answer.text()}`; return; }
  const { file: name, items } = await answer.json();
  live = false;
  socket?.close();
  info = { ...info, mode: "replay", file: name };
  store = emptyStore();
  $("mode").textContent = `replay · ${name}`;
  $("open-result").innerHTML = `<a href="/">back to live</a>`;
  startReplay(items);
}

async function startReplay(items) {
  $("replay").hidden = false;
  $("link").textContent = "replay"; $("link").className = "badge";
  $("replay-file").textContent = info.file || "";
  const times = items.map((x) => x[0]);
  const first = times[0] ?? 0, last = times.at(-1) ?? 0;
  let shown = -1, playing = false, lastTick = 0;
  const scrub = $("scrub");
  const seek = (t) => {
    const n = upperBound(times, t);
    if (n < shown) { store = emptyStore(); shown = 0; if (workspace) sceneView?.setWorkspace(workspace.workspace); }
    for (let k = Math.max(shown, 0); k < n; k++) apply(items[k][1], items[k][2], items[k][0]);
    shown = n; trim();
    $("replay-time").textContent = `${(t - first).toFixed(2)} / ${(last - first).toFixed(2)} s`;
  };
  const at = () => first + (scrub.value / 1000) * (last - first);
  scrub.oninput = () => seek(at());
  $("play").onclick = () => { playing = !playing; $("play").textContent = playing ? "❚❚" : "▶"; lastTick = performance.now();
    if (playing && scrub.value >= 1000) { scrub.value = 0; seek(at()); } };
  document.addEventListener("keydown", (e) => { if (e.key === "p") $("play").click(); });
  const tick = (now) => {
    if (playing && last > first) {
      const t = Math.min(last, at() + (now - lastTick) / 1000);
      scrub.value = ((t - first) / (last - first)) * 1000;
      seek(t);
      if (t >= last) $("play").click();
    }
    lastTick = now;
    requestAnimationFrame(tick);
  };
  requestAnimationFrame(tick);
  seek(at());
}

function upperBound(sorted, t) {
  let lo = 0, hi = sorted.length;
  while (lo < hi) { const mid = (lo + hi) >> 1; if (sorted[mid] <= t) lo = mid + 1; else hi = mid; }
  return lo;
}

// --------------------------------------------------------------------- drawing loop

function pointing() {
  if (store.gaze?.source === "pointing") return true;
  const last = store.staticP.at(-1);
  return !!last && last.names[last.probs.indexOf(Math.max(...last.probs))] === "point";
}

function focus() {
  const s = store.summaries.at(-1);
  return s?.focus || null;
}

// MediaPipe's 21 landmarks: the wrist, then four per finger, thumb first; bones between them
const HAND_LINKS = [[0, 1], [0, 5], [0, 17], [5, 9], [9, 13], [13, 17],
  ...[1, 5, 9, 13, 17].flatMap((b) => [[b, b + 1], [b + 1, b + 2], [b + 2, b + 3]])];
const SIDE_COLOURS = { left: "#39c5cf", right: "#f778ba" };

// The camera's image (cbgo/camera/preview) with the hands' landmarks drawn on it, so a user
// sees what the camera-bridge sees beside the 3D hand it made of it.
function drawCamera() {
  const preview = store.preview;
  if (!preview) return;
  const image = new Image();
  image.onload = () => {
    const canvas = $("camera"), g = canvas.getContext("2d");
    canvas.width = preview.width; canvas.height = preview.height;
    g.drawImage(image, 0, 0);
    g.lineWidth = 2;
    for (const hand of preview.hands) {
      const px = hand.points.map(([x, y]) => [x * preview.width, y * preview.height]);
      g.strokeStyle = g.fillStyle = SIDE_COLOURS[hand.side] || "#fff";
      g.beginPath();
      for (const [a, b] of HAND_LINKS) { g.moveTo(...px[a]); g.lineTo(...px[b]); }
      g.stroke();
      for (const [x, y] of px) g.fillRect(x - 2, y - 2, 4, 4);
    }
    const hands = preview.hands.map((h) => `${h.side} hand`).join(", ") || "no hand";
    $("camera-caption").textContent = `camera · ${hands}`;
    $("camera-view").hidden = false;
  };
  image.src = preview.src;
}

let lastCharts = 0;
function draw(now) {
  // The next frame first: a panel that throws is reported (the console, the page's error
  // event) without stopping every other panel's redraws.
  requestAnimationFrame(draw);
  const d = store.dirty, any = (...topics) => d.has("all") || topics.some((t) => d.has(t));
  store.dirty = new Set();
  trim();
  if (sceneView) {
    sceneView.setObjects(store.scene, sceneTarget());
    if (any("hands/frame", "robot/state", "gaze", "scene/state", "episode/summary"))
      sceneView.setDynamic({ hands: store.hands, robot: store.robot, scene: store.scene, gaze: store.gaze,
        focus: focus(), pointing: pointing() });
    sceneView.render();
  }
  if (any("camera/preview")) drawCamera();
  if (any("intent", "episode/summary", "scene/state")) drawIntent();
  if (any("intent", "episode/summary")) drawFeedback();  // not on scenes: keep the user's choice
  if (any("intent/clarify")) drawClarify();
  // cbgo/user repeats: redraw (and lose what is typed) only when the user shown changes
  const newUser = any("user") && mappingUser === null && store.user !== mappingDrawnFor;
  if (any("@mapping") || newUser) drawMapping();
  if (newUser) followMapping();
  if (any("plan/status", "robot/state", "scene/state", "robot/stop", "@services")) drawPlan();
  if (any("@services")) drawServices();
  if (now - lastCharts > 100) {  // the charts move with time: 10 redraws a second are plenty
    drawGestures(); drawEpisodes(); lastCharts = now;
  }
  if (store.user) $("user").textContent = `user: ${store.user}`;
}

async function main() {
  info = await (await fetch("/api/info")).json();
  workspace = { workspace: info.workspace, source: info.source };
  $("mode").textContent = info.mode === "live" ? `live · ${info.prefix}/**` : `replay · ${info.file}`;
  sceneView = new SceneView($("scene"), $("scene-labels"));
  sceneView.setWorkspace(info.workspace);
  $("scene-legend").innerHTML = `<i style="background:#39c5cf"></i>left hand<i style="background:#f778ba"></i>right hand
    <i style="background:#ff7b72"></i>gaze<i style="background:#e3b341"></i>focus / pointing ray
    <i style="background:#3fb950"></i>TCP<i style="background:#ffe066"></i>target · grid: ${esc(info.source)}`;
  $("stop").onclick = stop;
  document.addEventListener("keydown", (e) => { if (e.key === "Escape") { e.preventDefault(); stop(); } });
  $("open").onchange = (e) => e.target.files[0] && openRecording(e.target.files[0]);
  if (info.mode === "live") connect(); else await startReplay(await (await fetch("/api/replay")).json());
  requestAnimationFrame(draw);
}

main();

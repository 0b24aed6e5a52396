// Time charts drawn on a 2D canvas: lines (static p, evidence), spans (dynamic windows,
// episodes), a threshold and event markers. No chart library: the page must work offline and
// these few shapes do not need one.

const PALETTE = ["#58a6ff", "#f778ba", "#3fb950", "#d29922", "#bc8cff", "#ff7b72", "#39c5cf",
  "#e3b341", "#8b949e", "#a5d6ff", "#ffa657", "#7ee787", "#d2a8ff"];
const colours = new Map();

export function colourOf(name) {
  if (!colours.has(name)) colours.set(name, PALETTE[colours.size % PALETTE.length]);
  return colours.get(name);
}

// Sizes the canvas's bitmap to its CSS box (sharp on any screen); returns the 2D context.
function prepare(canvas) {
  const ratio = window.devicePixelRatio || 1;
  const w = Math.max(1, Math.round(canvas.clientWidth * ratio));
  const h = Math.max(1, Math.round(canvas.clientHeight * ratio));
  if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
  const ctx = canvas.getContext("2d");
  ctx.setTransform(ratio, 0, 0, ratio, 0, 0);
  ctx.clearRect(0, 0, canvas.clientWidth, canvas.clientHeight);
  return ctx;
}

function frame(canvas, t0, t1) {
  const W = canvas.clientWidth, H = canvas.clientHeight, left = 28, bottom = 14, top = 4;
  return {
    W, H, left, bottom, top,
    x: (t) => left + ((t - t0) / (t1 - t0)) * (W - left - 4),
    y: (v) => top + (1 - v) * (H - top - bottom),
  };
}

function axes(ctx, f, t0, t1) {
  ctx.strokeStyle = "#2c333e"; ctx.fillStyle = "#8893a2"; ctx.font = "10px sans-serif";
  ctx.lineWidth = 1;
  for (const v of [0, 0.5, 1]) {
    ctx.beginPath(); ctx.moveTo(f.left, f.y(v)); ctx.lineTo(f.W - 4, f.y(v)); ctx.stroke();
    ctx.fillText(v.toFixed(1), 2, f.y(v) + 3);
  }
  for (let s = Math.ceil(t0); s <= t1; s += 2) {
    ctx.fillText(`${Math.round(s - t1)}s`, f.x(s) - 8, f.H - 2);
  }
}

function legend(ctx, f, names) {
  ctx.font = "10px sans-serif";
  let x = f.left + 4;
  for (const name of names) {
    ctx.fillStyle = colourOf(name); ctx.fillRect(x, f.top + 2, 8, 8);
    ctx.fillStyle = "#dde3ea"; ctx.fillText(name, x + 11, f.top + 10);
    x += ctx.measureText(name).width + 22;
  }
}

// series: Map name -> [[t, v], ...]; options: {threshold, markers: [{t, label}], minPeak}.
export function lines(canvas, series, t0, t1, options = {}) {
  const ctx = prepare(canvas), f = frame(canvas, t0, t1);
  axes(ctx, f, t0, t1);
  const shown = [...series.entries()].filter(([, pts]) =>
    pts.some(([, v]) => v >= (options.minPeak ?? 0.05)));
  for (const [name, pts] of shown) {
    ctx.strokeStyle = colourOf(name); ctx.lineWidth = 1.6; ctx.beginPath();
    pts.forEach(([t, v], i) => (i ? ctx.lineTo(f.x(t), f.y(v)) : ctx.moveTo(f.x(t), f.y(v))));
    ctx.stroke();
  }
  if (options.threshold !== undefined) {
    ctx.setLineDash([5, 4]); ctx.strokeStyle = "#ff7b72"; ctx.beginPath();
    ctx.moveTo(f.left, f.y(options.threshold)); ctx.lineTo(f.W - 4, f.y(options.threshold));
    ctx.stroke(); ctx.setLineDash([]);
    ctx.fillStyle = "#ff7b72"; ctx.fillText(`E_t ${options.threshold}`, f.W - 50, f.y(options.threshold) - 3);
  }
  markers(ctx, f, options.markers || []);
  legend(ctx, f, shown.map(([n]) => n));
  if (!shown.length) empty(ctx, f, options.empty || "nothing in this window");
}

// spans: [{t0, t1, name, v}] drawn as steps at height v.
export function spans(canvas, items, t0, t1, options = {}) {
  const ctx = prepare(canvas), f = frame(canvas, t0, t1);
  axes(ctx, f, t0, t1);
  const names = [];
  for (const s of items) {
    if (s.v < (options.minPeak ?? 0.05)) continue;
    if (!names.includes(s.name)) names.push(s.name);
    ctx.strokeStyle = colourOf(s.name); ctx.lineWidth = 2; ctx.setLineDash([6, 3]);
    ctx.beginPath(); ctx.moveTo(f.x(Math.max(s.t0, t0)), f.y(s.v)); ctx.lineTo(f.x(s.t1), f.y(s.v));
    ctx.stroke(); ctx.setLineDash([]);
  }
  legend(ctx, f, names);
  if (!names.length) empty(ctx, f, options.empty || "no window in this time");
}

// Tick steps of the strip, s: the smallest that leaves at most 8 ticks.
const STRIP_STEPS = [10, 30, 60, 300, 600, 1800, 3600, 21600, 86400];

// A time before now in the unit of the tick step, so that every tick is exact (-90s, -5m).
function ago(seconds, step) {
  if (step < 60) return `${Math.round(seconds)}s`;
  return step < 3600 ? `${Math.round(seconds / 60)}m` : `${Math.round(seconds / 3600)}h`;
}

// Episodes on a strip: one bar per episode, labelled with its leading gesture.
export function strip(canvas, episodes, t0, t1) {
  const ctx = prepare(canvas), f = frame(canvas, t0, t1);
  ctx.fillStyle = "#8893a2"; ctx.font = "10px sans-serif";
  const step = STRIP_STEPS.find((s) => (t1 - t0) / s <= 8) ?? STRIP_STEPS.at(-1);
  for (let s = t1; s >= t0; s -= step) {
    if (s === t1) ctx.fillText("now", f.x(s) - 18, f.H - 2);
    else ctx.fillText(`-${ago(t1 - s, step)}`, f.x(s) - 8, f.H - 2);
  }
  for (const e of episodes) {
    const x0 = f.x(Math.max(e.t0, t0)), x1 = f.x(e.t1 ?? t1);
    ctx.fillStyle = e.open ? "#4d3b10" : "#1f3b5a";
    ctx.fillRect(x0, 8, Math.max(2, x1 - x0), f.H - 26);
    ctx.fillStyle = "#dde3ea"; ctx.fillText(e.label, x0 + 2, 22);
  }
  if (!episodes.length) empty(ctx, f, "no episode yet");
}

function markers(ctx, f, items) {
  ctx.font = "10px sans-serif";
  for (const m of items) {
    const x = f.x(m.t);
    ctx.strokeStyle = m.colour || "#e3b341"; ctx.lineWidth = 1.5; ctx.beginPath();
    ctx.moveTo(x, f.top); ctx.lineTo(x, f.H - f.bottom); ctx.stroke();
    ctx.fillStyle = m.colour || "#e3b341"; ctx.fillText(m.label, x + 2, f.H - f.bottom - 3);
  }
}

function empty(ctx, f, text) {
  ctx.fillStyle = "#5c6672"; ctx.font = "12px sans-serif";
  ctx.fillText(text, f.left + 10, f.H / 2 + 4);
}

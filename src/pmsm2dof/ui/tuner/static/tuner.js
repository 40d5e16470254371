/*
 * pmsm2dof tuner page: builds the controls the server describes, asks the server for a
 * run whenever a control changes and redraws the plots and the metrics table.
 *
 * Changes are coalesced: those within COALESCE_MS of the first make one request, and at
 * most one request is in flight; changes made while a run is computed make one request sent
 * when it returns. A response is drawn only if it is newer than what is on screen (latest
 * request wins). So the plots follow a moving slider at the pace the server allows.
 * Requests carry the page's client id: the server runs one simulation per client at a time
 * and answers 409 to a request that a newer one of the same client superseded.
 *
 * After a rejected request the plots stay, dimmed and marked stale, until a valid one
 * redraws them.
 */
"use strict";

const COALESCE_MS = 10;
/* No mode-bar button sends the chart anywhere: the page works offline and keeps its data local. */
const PLOT_CONFIG = { displaylogo: false, responsive: true, showSendToCloud: false, plotlyServerURL: "",
                      modeBarButtonsToRemove: ["lasso2d", "select2d", "sendChartToCloud"] };
const COLORS = { current: "#1f77b4", reference: "#222", pinned: "#aaa", limit: "#d62728", d: "#2ca02c",
                 gx: "#1f77b4", gn: "#ff7f0e", gxPinned: "#74a9cf", gnPinned: "#fdae6b" };
/* Shading of the spans at a limit: its fill, and the colour of its key in the titles. */
const SPANS = { current: { fill: "rgba(255, 165, 0, 0.2)", key: "#e69500", text: "current limit" },
                voltage: { fill: "rgba(148, 0, 211, 0.14)", key: "#9400d3", text: "voltage limit" } };
const CLIENT_ID = (self.crypto && crypto.randomUUID) ? crypto.randomUUID() : String(Math.random()).slice(2);

/* Public state, read by the benchmark and the browser test. */
window.tuner = {
  pending: true,      // a change is not drawn (or rejected) yet
  requestSeq: 0,      // number of the latest request sent
  renderedSeq: 0,     // number of the request whose response is on screen
  renderCount: 0,     // responses drawn
  errorCount: 0,      // 422 answers shown
  stale: false,       // the plots show the last valid settings, not the controls'
  lastLatencyMs: null, // control change -> plots redrawn, for the response on screen
  lastServerMs: null,  // server computing time for it
  lastFetchMs: null,   // request sent -> response parsed, for it
  current: null,      // response on screen
  pinned: null,       // pinned response
  suggestion: null,   // the last suggestion applied
  drive: null,        // drive mode: the drive panel's state (drive.js)
};

const state = { specs: {}, values: {}, changedAt: 0, inFlight: false, dirty: false, timer: null };

function el(tag, attrs, children) {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (k === "text") node.textContent = v;
    else node.setAttribute(k, v);
  }
  for (const c of children || []) node.appendChild(c);
  return node;
}

function fmt(x) {
  if (x === null || x === undefined) return "\u2013";
  if (typeof x !== "number") return String(x);
  if (!isFinite(x)) return String(x);
  if (x === 0) return "0";
  return Number(x.toPrecision(4)).toString();
}

/* ---- controls ---------------------------------------------------------------- */

function sliderToValue(spec, pos) {
  const f = pos / 1000;
  let v = spec.scale === "log"
    ? spec.min * Math.pow(spec.max / spec.min, f)
    : spec.min + f * (spec.max - spec.min);
  if (spec.quantum) v = Math.max(1, Math.round(v / spec.quantum)) * spec.quantum;
  return Number(v.toPrecision(4));
}

function valueToSlider(spec, v) {
  let f = spec.scale === "log"
    ? Math.log(v / spec.min) / Math.log(spec.max / spec.min)
    : (v - spec.min) / (spec.max - spec.min);
  if (!isFinite(f)) f = 0;
  return Math.round(1000 * Math.min(1, Math.max(0, f)));
}

function buildControl(spec) {
  const id = "ctl-" + spec.key.replace(/\W/g, "-");
  const label = el("label", { for: id, title: spec.help || spec.key, text: spec.label + (spec.unit ? " [" + spec.unit + "]" : "") });
  const row = el("div", { class: "control", "data-key": spec.key }, [label]);
  state.specs[spec.key] = spec;
  if (spec.kind === "select") {
    const select = el("select", { id: id, name: spec.key });
    for (const c of spec.choices) select.appendChild(el("option", { value: c, text: c }));
    select.value = spec.value;
    select.addEventListener("change", () => setValue(spec.key, select.value));
    row.appendChild(select);
    return row;
  }
  const range = el("input", { type: "range", min: "0", max: "1000", step: "1", "aria-label": spec.label });
  const box = el("input", { type: "text", id: id, name: spec.key, inputmode: "decimal" });
  row.append(range, box);
  if (spec.value !== null) {
    box.value = fmt(spec.value);
    range.value = valueToSlider(spec, spec.value);
  }
  range.addEventListener("input", () => { const v = sliderToValue(spec, Number(range.value)); box.value = fmt(v); setValue(spec.key, v); });
  box.addEventListener("change", () => {
    const text = box.value.trim();
    const v = text === "" || isNaN(Number(text)) ? text : Number(text);
    if (typeof v === "number" && isFinite(v)) range.value = valueToSlider(spec, v);
    setValue(spec.key, v);
  });
  if (spec.nullable) {
    const check = el("input", { type: "checkbox", id: id + "-default" });
    const option = el("label", { class: "option", for: id + "-default" }, [check, document.createTextNode(" " + spec.null_label)]);
    row.appendChild(el("span"));
    row.appendChild(option);
    const apply = () => {
      range.disabled = box.disabled = check.checked;
      setValue(spec.key, check.checked ? null : sliderToValue(spec, Number(range.value)));
    };
    check.checked = spec.value === null;
    range.disabled = box.disabled = check.checked;
    if (spec.value === null) { const v = spec.default_position; range.value = valueToSlider(spec, v); box.value = fmt(v); }
    check.addEventListener("change", apply);
  }
  return row;
}

function buildControls(description) {
  const form = document.getElementById("controls");
  for (const group of description.groups) {
    const fieldset = el("fieldset", {}, [el("legend", { text: group.legend })]);
    for (const spec of group.controls) {
      fieldset.appendChild(buildControl(spec));
      state.values[spec.key] = spec.value;
    }
    if (group.note) fieldset.appendChild(el("p", { class: "note", text: group.note }));
    form.appendChild(fieldset);
  }
  form.addEventListener("submit", (ev) => ev.preventDefault());
  updateDependencies();
}

/* Controls that only mean something for some choices are disabled for the others. */
function updateDependencies() {
  for (const [key, spec] of Object.entries(state.specs)) {
    if (!spec.enabled_when) continue;
    const [other, allowed] = spec.enabled_when;
    const on = allowed.includes(state.values[other]);
    const row = document.querySelector(`.control[data-key="${key}"]`);
    row.classList.toggle("disabled", !on);
    for (const input of row.querySelectorAll("input, select")) input.disabled = !on || (input.type !== "checkbox" && spec.nullable && state.values[key] === null);
  }
}

function setValue(key, value) {
  state.values[key] = value;
  updateDependencies();
  state.changedAt = performance.now();
  window.tuner.pending = true;
  if (state.timer === null) state.timer = setTimeout(() => { state.timer = null; requestRun(); }, COALESCE_MS);
}

/* The request: every control's value, except those disabled by another control. */
function requestBody() {
  const body = {};
  for (const [key, value] of Object.entries(state.values)) {
    const spec = state.specs[key];
    if (spec.enabled_when && !spec.enabled_when[1].includes(state.values[spec.enabled_when[0]])) {
      if (spec.value_when_disabled !== undefined) body[key] = spec.value_when_disabled;
      continue;
    }
    body[key] = value;
  }
  return body;
}

/* ---- requests ---------------------------------------------------------------- */

async function postJSON(path, body) {
  const response = await fetch(path, { method: "POST", body: JSON.stringify(body),
                                       headers: { "Content-Type": "application/json", "X-Pmsm2dof-Client": CLIENT_ID } });
  if (response.ok) return response;
  let message = `HTTP ${response.status}`;
  let param = null;
  try { const err = await response.json(); message = err.error; param = err.param; } catch (e) { /* not JSON */ }
  const error = new Error(message);
  error.param = param;
  error.status = response.status;
  throw error;
}

function showError(error) {
  const banner = document.getElementById("error");
  banner.textContent = error ? error.message : "";
  banner.hidden = !error;
  for (const row of document.querySelectorAll(".control.invalid")) row.classList.remove("invalid");
  if (error && error.param) {
    const row = document.querySelector(`.control[data-key="${error.param}"]`);
    if (row) row.classList.add("invalid");
  }
}

/* Plots and metrics of settings that are no longer the controls' are dimmed under a banner. */
function markStale(stale) {
  window.tuner.stale = stale;
  document.getElementById("plots").classList.toggle("stale", stale);
  document.getElementById("metrics").classList.toggle("stale", stale);
  document.getElementById("stale").hidden = !stale;
}

async function requestRun() {
  if (state.inFlight) { state.dirty = true; return; }
  state.inFlight = true;
  state.dirty = false;
  const seq = ++window.tuner.requestSeq;
  const changedAt = state.changedAt;
  document.getElementById("status").textContent = "computing\u2026";
  try {
    const sentAt = performance.now();
    const response = await postJSON("api/run", requestBody());
    const run = await response.json();
    const fetchMs = performance.now() - sentAt;
    if (seq > window.tuner.renderedSeq) {
      await render(run);
      window.tuner.renderedSeq = seq;
      window.tuner.renderCount += 1;
      await new Promise((resolve) => requestAnimationFrame(() => resolve()));
      window.tuner.lastLatencyMs = performance.now() - changedAt;
      window.tuner.lastServerMs = run.server_ms;
      window.tuner.lastFetchMs = fetchMs;
      showError(null);
      markStale(false);
      if (window.tuner.drive && window.tuner.drive.armed) driveWrite();  // validated: to the drive
      document.getElementById("status").textContent =
        `redrawn ${window.tuner.lastLatencyMs.toFixed(0)} ms after the change ` +
        `(server ${run.server_ms.toFixed(0)} ms, request ${fetchMs.toFixed(0)} ms)`;
    }
  } catch (error) {
    if (error.status === 409) {
      document.getElementById("status").textContent = "superseded by a newer request";
    } else {
      window.tuner.errorCount += 1;
      showError(error);
      if (window.tuner.current) markStale(true);
      document.getElementById("status").textContent = "not updated: see the message";
    }
  } finally {
    state.inFlight = false;
    if (state.dirty) requestRun();
    else if (state.timer === null) window.tuner.pending = false;
  }
}

async function download(kind) {
  try {
    const response = await postJSON("api/download/" + kind, requestBody());
    const disposition = response.headers.get("Content-Disposition") || "";
    const match = /filename="([^"]+)"/.exec(disposition);
    const blob = await response.blob();
    const url = URL.createObjectURL(blob);
    const a = el("a", { href: url, download: match ? match[1] : kind });
    document.body.appendChild(a);
    a.click();
    a.remove();
    setTimeout(() => URL.revokeObjectURL(url), 10000);
    showError(null);
  } catch (error) {
    showError(error);
  }
}

/* ---- suggest ------------------------------------------------------------------ */

/* Set a control's widgets and value as if the user had moved it. */
function setControl(key, value) {
  const spec = state.specs[key];
  const row = document.querySelector(`.control[data-key="${key}"]`);
  if (!spec || !row) return;
  if (spec.kind === "select") {
    row.querySelector("select").value = value;
  } else {
    const range = row.querySelector('input[type="range"]');
    const box = row.querySelector('input[type="text"]');
    const check = row.querySelector('input[type="checkbox"]');
    if (check) check.checked = value === null;
    if (value !== null) { box.value = fmt(value); range.value = valueToSlider(spec, value); }
    range.disabled = box.disabled = check ? check.checked : false;
  }
  setValue(key, value);
}

/* Autotune the experiment of the controls for the specification of the form; apply the design. */
async function suggest() {
  const button = document.getElementById("suggest-run");
  const result = document.getElementById("suggest-result");
  const number = (id) => { const t = document.getElementById(id).value.trim(); return t === "" ? null : Number(t); };
  const spec = { J_range: [number("suggest-J-lo"), number("suggest-J-hi")] };
  const overshoot = number("suggest-overshoot");
  if (overshoot !== null) spec.max_overshoot_pct = overshoot;
  button.disabled = true;
  result.textContent = "searching\u2026";
  try {
    const response = await postJSON("api/suggest", { values: requestBody(), spec: spec });
    const s = await response.json();
    for (const [key, value] of Object.entries(s.values)) setControl(key, value);
    result.textContent = (s.feasible ? "applied: it meets the specification" :
      "applied the closest design, which misses " + s.violations.join("; ")) +
      ` (worst load dip ${fmt(s.worst_case.load_dip_rpm_per_Nm)} rpm/Nm, load IAE ` +
      `${fmt(s.worst_case.load_iae_rpm_s_per_Nm)} rpm s/Nm; ${s.counts.runs} simulations in ` +
      `${s.wall_time_s.toFixed(1)} s)`;
    window.tuner.suggestion = s;
    showError(null);
  } catch (error) {
    result.textContent = error.status === 429 ? error.message : "";
    if (error.status !== 429) showError(error);
  } finally {
    button.disabled = false;
  }
}

/* ---- drawing ----------------------------------------------------------------- */
/*
 * One plotly figure holds the six plots (one redraw instead of six):
 *   x/y   speed and reference        x2/y2  current command and limit
 *   x3/y3 detail of the load step    x6/y6  voltage ||u_dq|| and the range u_dc/sqrt(3)
 *         (or of the last reference step without one)
 *   x4/y4 |Gx|, |GN|                 x5/y5  their phases
 * Spans at the current limit (orange) and at the voltage limit (purple) are shaded in the four
 * time plots. Titles carry the legends (plotly's legends are the slowest part of a redraw).
 */

const COLS = [[0, 0.45], [0.55, 1]];
const TOP = [0.72, 0.97];
const MIDDLE = [0.38, 0.63];
const BOTTOM = [0, 0.29];
const TIME_AXES = [["x", "y"], ["x2", "y2"], ["x3", "y3"], ["x6", "y6"]];
const SOLID = "\u2014\u2014";
const DASHED = "\u2013 \u2013";
const DOTTED = "\u00b7\u00b7\u00b7\u00b7";
const PATCH = "\u25ae";

function line(x, y, name, color, axes, dash) {
  return { x: x, y: y, name: name, type: "scatter", mode: "lines", xaxis: axes[0], yaxis: axes[1],
           line: { color: color, width: dash === "dot" ? 1.8 : 1.6, dash: dash || "solid" } };
}

function pinnedLine(x, y, name, axes) {
  return line(x, y, name, COLORS.pinned, axes, "dot");
}

function key(color, glyph, text) {
  return `<span style="color:${color}">${glyph} ${text}</span>`;
}

function title(x, y, text, keys) {
  return { xref: "paper", yref: "paper", x: x, y: y, xanchor: "left", yanchor: "bottom", showarrow: false,
           align: "left", text: `<b>${text}</b>    ` + keys.join("   "), font: { size: 12 } };
}

/* One time plot: the run's traces [x, y, name, color, dash], then the pinned run's copy of the
   main one [x, y, name], dotted grey. */
function timePlot(axes, traces, pinnedTrace) {
  const data = traces.map(([x, y, name, color, dash]) => line(x, y, name, color, axes, dash));
  if (pinnedTrace) data.push(pinnedLine(pinnedTrace[0], pinnedTrace[1], pinnedTrace[2], axes));
  return data;
}

function speedTraces(run, pinned) {
  const tr = run.traces;
  return timePlot(["x", "y"], [
    [tr.speed_ref_rpm.t, tr.speed_ref_rpm.y, "reference", COLORS.reference, "dash"],
    [tr.speed_rpm.t, tr.speed_rpm.y, "speed", COLORS.current],
  ], pinned && [pinned.traces.speed_rpm.t, pinned.traces.speed_rpm.y, "speed (pinned)"]);
}

function currentTraces(run, pinned) {
  const tr = run.traces;
  return timePlot(["x2", "y2"], [
    [[0, run.t_end_s], [run.i_max_A, run.i_max_A], "+i_max", COLORS.limit, "dash"],
    [[0, run.t_end_s], [-run.i_max_A, -run.i_max_A], "-i_max", COLORS.limit, "dash"],
    [tr.id_ref_A.t, tr.id_ref_A.y, "id command", COLORS.d],
    [tr.iq_ref_A.t, tr.iq_ref_A.y, "iq command", COLORS.current],
  ], pinned && [pinned.traces.iq_ref_A.t, pinned.traces.iq_ref_A.y, "iq command (pinned)"]);
}

function detailTraces(run, pinned) {
  const d = run.detail;
  return timePlot(["x3", "y3"], [
    [d.t, d.speed_ref_rpm, "reference", COLORS.reference, "dash"],
    [d.t, d.speed_rpm, "speed", COLORS.current],
  ], pinned && [pinned.detail.t, pinned.detail.speed_rpm, "speed (pinned)"]);
}

function voltageTraces(run, pinned) {
  const tr = run.traces;
  return timePlot(["x6", "y6"], [
    [tr.u_max_V.t, tr.u_max_V.y, "range u_dc/\u221a3", COLORS.limit, "dash"],
    [tr.u_dq_V.t, tr.u_dq_V.y, "||u_dq||", COLORS.current],
  ], pinned && [pinned.traces.u_dq_V.t, pinned.traces.u_dq_V.y, "||u_dq|| (pinned)"]);
}

/* Bode of the run, and of the pinned run dotted in lighter colours of its own per curve. */
function bodeTraces(run, pinned) {
  const data = [];
  const curves = [[run.bode, "", COLORS.gx, COLORS.gn, "solid"]];
  if (pinned) curves.unshift([pinned.bode, "pinned ", COLORS.gxPinned, COLORS.gnPinned, "dot"]);
  for (const [b, prefix, gx, gn, dash] of curves) {
    data.push(line(b.w_radps, b.Gx_dB, prefix + "|Gx| [dB]", gx, ["x4", "y4"], dash));
    data.push(line(b.w_radps, b.GN_dB, prefix + "|GN| [dB (rad/s)/Nm]", gn, ["x4", "y4"], dash));
    data.push(line(b.w_radps, b.Gx_deg, prefix + "\u2220Gx [deg]", gx, ["x5", "y5"], dash));
    data.push(line(b.w_radps, b.GN_deg, prefix + "\u2220GN [deg]", gn, ["x5", "y5"], dash));
  }
  return data;
}

function spanShapes(run) {
  const shapes = [];
  for (const [kind, span] of Object.entries(SPANS)) {
    for (const [t0, t1] of run.spans[kind]) {
      for (const [x, y] of TIME_AXES) {
        shapes.push({ type: "rect", xref: x, yref: y + " domain", x0: t0, x1: t1, y0: 0, y1: 1, layer: "below",
                      fillcolor: span.fill, line: { width: 0 }, name: span.text });
      }
    }
  }
  return shapes;
}

function figureLayout(run, pinned) {
  const w = run.detail.t;
  const nyquist = run.bode.w_nyquist_radps;
  const inView = nyquist <= run.bode.w_radps[run.bode.w_radps.length - 1];
  const axis = (text, extra) => Object.assign({ title: { text: text, standoff: 2, font: { size: 12 } } }, extra);
  const pinKey = pinned ? [key(COLORS.pinned, DOTTED, "pinned")] : [];
  const limitKeys = Object.entries(SPANS).filter(([kind]) => run.spans[kind].length)
    .map(([, span]) => key(span.key, PATCH, span.text));
  const bodeKeys = [key(COLORS.gx, SOLID, "Gx tracking"), key(COLORS.gn, SOLID, "GN load [(rad/s)/Nm]")];
  const pinnedBodeKeys = pinned ? [key(COLORS.gxPinned, DOTTED, "pinned Gx"), key(COLORS.gnPinned, DOTTED, "pinned GN")] : [];
  const annotations = [
    title(COLS[0][0], TOP[1], "Speed",
      [key(COLORS.current, SOLID, "speed"), key(COLORS.reference, DASHED, "reference")].concat(pinKey, limitKeys)),
    title(COLS[1][0], TOP[1], "Current command",
      [key(COLORS.current, SOLID, "iq"), key(COLORS.d, SOLID, "id"), key(COLORS.limit, DASHED, "\u00b1i_max")].concat(pinKey)),
    title(COLS[0][0], MIDDLE[1], run.detail.title,
      [key(COLORS.current, SOLID, "speed"), key(COLORS.reference, DASHED, "reference")].concat(pinKey)),
    title(COLS[1][0], MIDDLE[1], "Voltage",
      [key(COLORS.current, SOLID, "||u_dq||"), key(COLORS.limit, DASHED, "range u_dc/\u221a3")].concat(pinKey)),
    title(COLS[0][0], BOTTOM[1], "Bode magnitude (eq 6, 8)", bodeKeys),
    title(COLS[1][0], BOTTOM[1], "Bode phase", pinnedBodeKeys),
  ];
  const shapes = spanShapes(run);
  // pi/Ts, where the sampled controller leaves the continuous design, when it is in view
  if (inView) {
    for (const [x, y] of [["x4", "y4"], ["x5", "y5"]]) {
      shapes.push({ type: "line", xref: x, yref: y + " domain", x0: nyquist, x1: nyquist, y0: 0, y1: 1,
                    line: { color: "#999", width: 1, dash: "dot" } });
      annotations.push({ xref: x, yref: y + " domain", x: Math.log10(nyquist), y: 1, text: "\u03c0/Ts",
                         showarrow: false, xanchor: "right", yanchor: "top", font: { size: 10, color: "#777" } });
    }
  }
  return {
    showlegend: false,
    hovermode: "closest",
    uirevision: "keep",
    margin: { l: 62, r: 12, t: 22, b: 42 },
    xaxis: axis("t [s]", { domain: COLS[0], anchor: "y" }),
    yaxis: axis("speed [rpm]", { domain: TOP, anchor: "x" }),
    xaxis2: axis("t [s]", { domain: COLS[1], anchor: "y2" }),
    yaxis2: axis("current [A]", { domain: TOP, anchor: "x2" }),
    xaxis3: axis("t [s]", { domain: COLS[0], anchor: "y3", range: [w[0], w[w.length - 1]] }),
    yaxis3: axis("speed [rpm]", { domain: MIDDLE, anchor: "x3" }),
    xaxis6: axis("t [s]", { domain: COLS[1], anchor: "y6" }),
    yaxis6: axis("voltage [V]", { domain: MIDDLE, anchor: "x6", rangemode: "tozero" }),
    xaxis4: axis("\u03c9 [rad/s]", { domain: COLS[0], anchor: "y4", type: "log" }),
    yaxis4: axis("magnitude [dB]", { domain: BOTTOM, anchor: "x4" }),
    xaxis5: axis("\u03c9 [rad/s]", { domain: COLS[1], anchor: "y5", type: "log" }),
    yaxis5: axis("phase [deg]", { domain: BOTTOM, anchor: "x5" }),
    annotations: annotations,
    shapes: shapes,
  };
}

function renderMetrics(run, pinned) {
  const body = document.querySelector("#metrics tbody");
  body.replaceChildren();
  const pinnedRows = new Map(pinned ? pinned.metrics.map((m) => [m.key, m]) : []);
  let group = null;
  for (const m of run.metrics) {
    if (m.group !== group) {
      group = m.group;
      body.appendChild(el("tr", { class: "group" }, [el("th", { colspan: "3", text: group })]));
    }
    const p = pinnedRows.get(m.key);
    const warn = m.key === "run.voltage_limit_time_s" && m.value > 0;
    body.appendChild(el("tr", { "data-metric": m.key, class: warn ? "warning" : "" }, [
      el("td", { text: m.label + (m.unit ? " [" + m.unit + "]" : "") }),
      el("td", { class: "current", text: fmt(m.value), title: m.reason }),
      el("td", { class: "pinned", text: p ? fmt(p.value) : "", title: p ? p.reason : "" }),
    ]));
  }
  const warning = document.getElementById("warning");
  warning.textContent = run.warnings.join(" ");
  warning.hidden = run.warnings.length === 0;
  const d = run.design;
  const log = run.log;
  document.getElementById("design").textContent =
    `Kp = ${fmt(d.Kp)} Nm/(rad/s), Ki = ${fmt(d.Ki)} Nm/rad, Ka = ${fmt(d.Ka)} (rad/s)/Nm (eq 9); ` +
    `plots and metrics from ${log.rows} samples, one every ${fmt(1e3 * log.period_s)} ms` +
    (pinned ? ` \u2014 pinned: ${pinned.label}` : "");
}

async function render(run) {
  const previous = window.tuner.current;
  if (previous && previous.bode.key === run.bode.key) {
    run.bode = previous.bode;  // the same arrays: plotly does not recompute those traces
  }
  window.tuner.current = run;
  const pinned = window.tuner.pinned;
  const data = [].concat(speedTraces(run, pinned), currentTraces(run, pinned), detailTraces(run, pinned),
                         voltageTraces(run, pinned), bodeTraces(run, pinned));
  await Plotly.react("plot", data, figureLayout(run, pinned), PLOT_CONFIG);
  renderMetrics(run, pinned);
}

function pin() {
  const run = window.tuner.current;
  if (!run) return;
  window.tuner.pinned = run;
  document.getElementById("unpin").disabled = false;
  return render(run);
}

function unpin() {
  window.tuner.pinned = null;
  document.getElementById("unpin").disabled = true;
  if (window.tuner.current) return render(window.tuner.current);
}

async function start() {
  try {
    const response = await fetch("api/controls");
    const description = await response.json();
    document.getElementById("scenario-name").textContent = "scenario: " + description.name;
    buildControls(description);
    startDrive(description.drive);
  } catch (error) {
    showError(new Error("cannot load the controls: " + error.message));
    return;
  }
  document.getElementById("pin").addEventListener("click", pin);
  document.getElementById("unpin").addEventListener("click", unpin);
  document.getElementById("download-toml").addEventListener("click", () => download("scenario.toml"));
  document.getElementById("download-header").addEventListener("click", () => download("header.h"));
  document.getElementById("download-csv").addEventListener("click", () => download("trace.csv"));
  document.getElementById("suggest-run").addEventListener("click", suggest);
  state.changedAt = performance.now();
  requestRun();
}

start();

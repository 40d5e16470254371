/*
 * pmsm2dof tuner, drive mode (pmsm2dof tune SCENARIO --link URL): the panel that arms the drive,
 * writes each validated change of a control to it, runs the experiment on it and draws the
 * captured response over its simulation (the twin), their difference and the metrics of both.
 *
 * Nothing is written unless the page armed the drive. An armed page sends a heartbeat every
 * HEARTBEAT_MS; the server disarms the drive and stops it when none comes for its
 * heartbeat_timeout_s (a closed or frozen page). A change is written after the tuner's run of the
 * same values succeeded (the server validates it again before writing); one write at a time, the
 * latest values last. Loaded before tuner.js, whose el, fmt, postJSON, requestBody and
 * PLOT_CONFIG it uses once called.
 */
"use strict";

const DRIVE_COLORS = { drive: "#d62728", twin: "#1f77b4", reference: "#222" };

/* window.tuner.drive in drive mode (read by the browser test). */
const DRIVE = {
  info: null,         // the drive's link, from api/controls
  armed: false,       // the server said this page holds the arming
  writes: 0,          // writes the drive took
  written: null,      // the drive's speed controller read back after the last write
  writeErrors: 0,     // writes refused (not armed, rejected, link failed)
  run: null,          // the last run drawn: drive, twin, difference, comparison, metrics
  runs: 0,            // runs drawn
  message: "",        // the last sentence shown in the panel
  alarm: false,       // it reports a failure (a lost page, a dropped link, a refusal)
};

const driveState = { heartbeat: null, writing: false, again: false };

function driveSay(text, alarm) {
  const d = window.tuner.drive;
  d.message = text;
  d.alarm = alarm;
  const p = document.getElementById("drive-status");
  p.textContent = text;
  p.classList.toggle("alarm", alarm);
}

function driveArmed(armed) {
  const d = window.tuner.drive;
  d.armed = armed;
  document.getElementById("drive-arm").checked = armed;
  document.getElementById("drive-run").disabled = !armed;
  document.getElementById("drive").classList.toggle("armed", armed);
  if (armed && driveState.heartbeat === null) {
    const period = Math.min(1000, 1000 * d.info.heartbeat_timeout_s / 3);
    driveState.heartbeat = setInterval(heartbeat, period);
  } else if (!armed && driveState.heartbeat !== null) {
    clearInterval(driveState.heartbeat);
    driveState.heartbeat = null;
  }
}

async function heartbeat() {
  try {
    const response = await postJSON("api/drive/heartbeat", {});
    const beat = await response.json();
    if (!beat.armed && window.tuner.drive.armed) {
      driveArmed(false);
      const last = beat.messages[beat.messages.length - 1];
      driveSay("disarmed by the server" + (last ? ": " + last : ""), true);
    } else if (beat.lost) {
      driveSay(beat.lost, true);
    }
  } catch (error) {
    driveSay("the tuner's server does not answer: " + error.message, true);
  }
}

async function arm(event) {
  const wanted = event.target.checked;
  try {
    const response = await postJSON("api/drive/arm", { armed: wanted });
    const status = await response.json();
    driveArmed(status.armed);
    driveSay(status.armed ? `armed: changes are written to the drive (state ${status.state})`
                          : `disarmed: nothing is written (state ${status.state})`, false);
    if (status.armed) driveWrite();
  } catch (error) {
    driveArmed(false);
    driveSay(error.message, true);
  }
}

/* Write the controls' values to the drive: called after each run of the tuner succeeded. */
async function driveWrite() {
  if (!window.tuner.drive.armed) return;
  if (driveState.writing) { driveState.again = true; return; }
  driveState.writing = true;
  driveState.again = false;
  try {
    const response = await postJSON("api/drive/write", requestBody());
    const written = await response.json();
    const d = window.tuner.drive;
    d.written = written.config;
    d.writes += 1;
    driveSay(`written: \u03b1 = ${fmt(written.config.alpha_radps)} rad/s, \u03b6 = ${fmt(written.config.zeta)}, ` +
             `m = ${fmt(written.config.m)}, Ka = ${fmt(written.config.Ka)} (read back from the drive)`, false);
  } catch (error) {
    window.tuner.drive.writeErrors += 1;
    if (error.status === 409) driveArmed(false);
    driveSay("not written: " + error.message, true);
  } finally {
    driveState.writing = false;
    if (driveState.again) driveWrite();
  }
}

async function driveRun() {
  const button = document.getElementById("drive-run");
  button.disabled = true;
  driveSay("running on the drive\u2026", false);
  try {
    const response = await postJSON("api/drive/run", requestBody());
    const run = await response.json();
    await renderDrive(run);
    const c = run.comparison;
    driveSay(`run of ${run.samples} samples in ${run.drive_s.toFixed(2)} s: largest difference from the twin ` +
             `${fmt(c.speed.max_abs_difference)} rad/s (${fmt(c.speed.relative_to_step)} of the step), ` +
             `${fmt(c.currents.max_abs_difference)} A (${fmt(c.currents.relative_to_step)} of the step)`, false);
  } catch (error) {
    if (error.status === 409) driveArmed(false);
    driveSay("run failed: " + error.message, true);
  } finally {
    button.disabled = !window.tuner.drive.armed;
  }
}

function driveLine(x, y, name, color, axes, dash) {
  return { x: x, y: y, name: name, type: "scatter", mode: "lines", xaxis: axes[0], yaxis: axes[1],
           line: { color: color, width: 1.6, dash: dash || "solid" } };
}

async function renderDrive(run) {
  const d = run.drive, t = run.twin, e = run.difference;
  const data = [
    driveLine(t.t, t.speed_ref_rpm, "speed reference", DRIVE_COLORS.reference, ["x", "y"], "dot"),
    driveLine(t.t, t.speed_rpm, "twin speed", DRIVE_COLORS.twin, ["x", "y"], "dash"),
    driveLine(d.t, d.speed_rpm, "drive speed", DRIVE_COLORS.drive, ["x", "y"]),
    driveLine(t.t, t.iq_A, "twin iq", DRIVE_COLORS.twin, ["x2", "y2"], "dash"),
    driveLine(d.t, d.iq_A, "drive iq", DRIVE_COLORS.drive, ["x2", "y2"]),
    driveLine(e.t, e.speed_rpm, "speed difference", DRIVE_COLORS.drive, ["x3", "y3"]),
    driveLine(e.t, e.iq_A, "iq difference", DRIVE_COLORS.drive, ["x4", "y4"]),
  ];
  const axis = (title, domain, anchor) => ({ title: { text: title }, domain: domain, anchor: anchor });
  const layout = {
    margin: { l: 70, r: 20, t: 30, b: 40 }, showlegend: true, legend: { orientation: "h", y: 1.06 },
    xaxis: { domain: [0, 1], anchor: "y", matches: "x4", showticklabels: false },
    xaxis2: { domain: [0, 1], anchor: "y2", matches: "x4", showticklabels: false },
    xaxis3: { domain: [0, 1], anchor: "y3", matches: "x4", showticklabels: false },
    xaxis4: { domain: [0, 1], anchor: "y4", title: { text: "t [s]" } },
    yaxis: axis("speed [rpm]", [0.58, 1.0], "x"),
    yaxis2: axis("iq [A]", [0.32, 0.55], "x2"),
    yaxis3: axis("\u0394 speed [rpm]", [0.16, 0.29], "x3"),
    yaxis4: axis("\u0394 iq [A]", [0.0, 0.13], "x4"),
    title: { text: "on the drive (solid) and its twin (dashed): " + run.label, font: { size: 12 } },
  };
  document.getElementById("drive-plot").hidden = false;
  await Plotly.react("drive-plot", data, layout, PLOT_CONFIG);
  const body = document.querySelector("#drive-metrics tbody");
  body.replaceChildren();
  let group = null;
  for (const m of run.metrics) {
    if (m.group !== group) {
      group = m.group;
      body.appendChild(el("tr", { class: "group" }, [el("th", { colspan: "3", text: group })]));
    }
    body.appendChild(el("tr", { "data-metric": m.key }, [
      el("td", { text: m.label + (m.unit ? " [" + m.unit + "]" : "") }),
      el("td", { class: "twin", text: fmt(m.twin), title: m.reason }),
      el("td", { class: "drive", text: fmt(m.drive), title: m.reason }),
    ]));
  }
  document.getElementById("drive-metrics").hidden = false;
  window.tuner.drive.run = run;
  window.tuner.drive.runs += 1;
}

/* Called by tuner.js once the controls are built, with api/controls' "drive" (null: no drive). */
function startDrive(info) {
  if (!info) return;
  DRIVE.info = info;
  window.tuner.drive = DRIVE;
  document.getElementById("drive").hidden = false;
  document.getElementById("drive-link").textContent =
    `${info.url}${info.virtual ? " (virtual drive)" : ""}; arming needs a heartbeat of this page ` +
    `every ${fmt(info.heartbeat_timeout_s)} s`;
  document.getElementById("drive-arm").addEventListener("change", arm);
  document.getElementById("drive-run").addEventListener("click", driveRun);
  driveSay("disarmed: nothing is written to the drive", false);
}

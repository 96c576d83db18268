// The monitor's page: the state from /api/state, then every update from /api/stream (Server-Sent
// Events, reconnected by the browser with the last update's number). Read-only: it sends nothing but
// GET requests. Every text goes in with textContent, never as markup.
"use strict";

const byId = (id) => document.getElementById(id);
let shownEvents = 0; // the number of the last event line shown
let lastSeq = 0;
let server = null; // the server's id: another one (a restarted bench) numbers its states anew

function text(id, value) {
  byId(id).textContent = value;
}

function fixed(value, digits) {
  return value === null || value === undefined ? "-" : value.toFixed(digits);
}

function clock(seconds) {
  if (seconds === null || seconds === undefined) return "-";
  const s = Math.round(seconds);
  const h = Math.floor(s / 3600), m = Math.floor((s % 3600) / 60), r = s % 60;
  const two = (n) => String(n).padStart(2, "0");
  return h ? `${h}:${two(m)}:${two(r)}` : `${m}:${two(r)}`;
}

function rows(table, pairs) {
  table.replaceChildren(...pairs.map(([name, value]) => {
    const row = document.createElement("tr");
    const head = document.createElement("th");
    const cell = document.createElement("td");
    head.textContent = name;
    cell.textContent = value;
    row.append(head, cell);
    return row;
  }));
}

function showSequence(state) {
  const seq = state.sequence;
  text("sequence-name", seq ? seq.name : "no sequence started");
  const status = byId("sequence-status");
  status.textContent = seq ? seq.status + (seq.reason ? `: ${seq.reason}` : "") : "";
  status.className = seq ? `status-${seq.status}` : "";
  text("step", state.step || "");
  const prompt = byId("prompt");
  prompt.hidden = !state.prompt;
  prompt.textContent = state.prompt ? `waiting for the operator: ${state.prompt}` : "";
  text("points", `${state.points_done}/${state.points_planned}`);
  text("points-before", state.points_done_before ? `(${state.points_done_before} done before the resume)` : "");
  text("elapsed", clock(state.elapsed_s));
  const ended = seq && seq.status !== "running";
  text("eta", ended ? seq.status : clock(state.eta_s) + (state.awaiting_operator ? " (waiting for the operator)" : ""));
}

function showLive(live) {
  const v = live ? live.values : {};
  text("fz", fixed(v.fz_wfs_n, 1));
  text("f-plate", fixed(v.f_plate_n, 1));
  text("z", v.z_base_m === null || v.z_base_m === undefined ? "-" : (v.z_base_m * 1e3).toFixed(3));
  text("a-hub", fixed(v.a_hub_m_s2, 2));
  text("live-note", live ? `newest ${fixed(live.age_s, 1)} s ago${live.run ? ", run " + live.run : ""}` :
    "no live values: the WFS streams during runs only");
}

function showLamps(lamps) {
  byId("lamps").replaceChildren(...lamps.map((lamp) => {
    const item = document.createElement("li");
    item.textContent = lamp.text;
    item.className = lamp.ok === true ? "ok" : lamp.ok === false ? "tripped" : "unknown";
    return item;
  }));
}

function showAnalyses(analyses) {
  const box = byId("analyses");
  if (!analyses.length) {
    const none = document.createElement("p");
    none.textContent = "none yet";
    box.replaceChildren(none);
    return;
  }
  box.replaceChildren(...analyses.map((a) => {
    const part = document.createElement("div");
    const head = document.createElement("h3");
    head.textContent = `${a.run_id}: ${a.analysis}, ${a.status}${a.why ? " (" + a.why + ")" : ""}`;
    const list = document.createElement("ul");
    const flagged = new Set(a.flags.map((f) => f.flag));
    for (const line of a.summary) {
      const item = document.createElement("li");
      item.textContent = line;
      if (flagged.has(line)) item.className = "flag";
      list.append(item);
    }
    part.append(head, list);
    return part;
  }));
}

function showEvents(events, total) {
  const list = byId("events");
  const fresh = events.filter((e) => e.n > shownEvents);
  if (fresh.length && fresh[0].n > shownEvents + 1) {
    const missed = byId("events-missed");
    missed.hidden = false;
    missed.textContent = `${fresh[0].n - shownEvents - 1} earlier event line(s) not shown (see the campaign file)`;
  }
  for (const e of fresh) {
    const item = document.createElement("li");
    item.value = e.n;
    item.textContent = e.text;
    list.append(item);
  }
  if (fresh.length) {
    shownEvents = fresh[fresh.length - 1].n;
    list.scrollTop = list.scrollHeight;
  }
}

function show(state) {
  if (typeof state.seq !== "number") return;
  if (state.server !== server) { // a restarted bench: start again
    server = state.server;
    lastSeq = 0;
    shownEvents = 0;
    byId("events").replaceChildren();
  }
  if (state.seq <= lastSeq) return;
  lastSeq = state.seq;
  text("seq", String(state.seq));
  text("bench", state.bench || "");
  const stateBox = byId("state");
  stateBox.textContent = state.state;
  stateBox.className = `tone-${state.tone || "plain"}`;
  showSequence(state);
  showLive(state.live);
  showLamps(state.lamps || []);
  rows(byId("counters"), Object.entries(state.counters || {}).map(([k, v]) => [k.replaceAll("_", " "), String(v)]));
  showAnalyses(state.analyses || []);
  showEvents(state.events || [], state.events_total || 0);
}

function connected(up) {
  const box = byId("connection");
  box.textContent = up ? "live" : "reconnecting…";
  box.className = up ? "up" : "down";
}

async function start() {
  try {
    const answer = await fetch("/api/state", { credentials: "same-origin" });
    if (answer.ok) show(await answer.json());
  } catch (error) {
    connected(false);
  }
  const stream = new EventSource("/api/stream");
  stream.addEventListener("state", (message) => show(JSON.parse(message.data)));
  stream.onopen = () => connected(true);
  stream.onerror = () => connected(false);
}

start();

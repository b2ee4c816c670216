// The fieldgate console: one server-sent event stream (/events) brings the plant twice a
// second, and, while the Bus tab is open, every frame of every bus. Nothing here sends
// anything to the plant.
"use strict";

const token = new URLSearchParams(location.search).get("token");
const withToken = (path) =>
  token ? path + (path.includes("?") ? "&" : "?") + "token=" + encodeURIComponent(token) : path;

const TRACE_KEEP = 5000;      // frames the page keeps (and downloads)
const PLOT_SECONDS = 60;
const traceFrames = [];
const positions = new Map();  // axis name -> [[time ms, position], ...]
let tracePaused = false;
let source = null;
let sourceWithTrace = false;
let lastPlant = null;

function cell(row, text, cls) {
  const td = row.insertCell();
  td.textContent = text === null || text === undefined ? "—" : String(text);
  if (cls) td.className = cls;
  return td;
}

// A code as the docs give it: hex, 4 digits at least (65530 -> 0xfffa).
function hex(code) {
  return "0x" + (code >>> 0).toString(16).padStart(4, "0");
}

// The wall clock as the trace gives it: UTC, 24 h.
function utcTime(ms) {
  return new Date(ms).toISOString().slice(0, 19).replace("T", " ") + " UTC";
}

function age(ms) {
  if (ms === null || ms === undefined) return "never";
  return ms < 1000 ? ms + " ms" : (ms / 1000).toFixed(1) + " s";
}

function renderNodes(plant) {
  const body = document.querySelector("#nodes tbody");
  body.replaceChildren();
  for (const n of plant.nodes) {
    const row = body.insertRow();
    row.dataset.node = n.name;
    row.dataset.state = n.state;
    cell(row, n.name);
    cell(row, n.bus);
    cell(row, n.address);
    cell(row, n.model);
    cell(row, n.unit, "num");
    cell(row, n.state, "state state-" + n.state);
    cell(row, n.reason || "", "text");
    cell(row, n.transactions, "num");
    cell(row, n.timeouts, "num");
    cell(row, n.errors, "num");
    cell(row, age(n.last_good_age_ms), "num");
    cell(row, n.last_device_error ? hex(n.last_device_error) + ": " + n.last_error_text : "",
         "text");
  }
}

function renderBuses(plant) {
  const body = document.querySelector("#buses tbody");
  body.replaceChildren();
  const select = document.getElementById("trace-bus");
  for (const b of plant.buses) {
    const row = body.insertRow();
    row.dataset.bus = b.name;
    cell(row, b.name);
    cell(row, b.protocol);
    cell(row, b.link, "text");
    cell(row, b.link_up ? "yes" : "no");
    cell(row, b.transactions, "num");
    cell(row, b.timeouts, "num");
    cell(row, b.errors, "num");
    cell(row, b.retries, "num");
    cell(row, b.resyncs, "num");
    cell(row, b.alignment_proofs + " (" + b.alignment_failures + ")", "num");
    cell(row, b.trace ? "on" : "off");
    if (![...select.options].some((o) => o.value === b.name)) select.add(new Option(b.name, b.name));
  }
}

function renderListeners(plant) {
  const body = document.querySelector("#listeners tbody");
  body.replaceChildren();
  const clients = document.querySelector("#clients tbody");
  clients.replaceChildren();
  for (const l of plant.listeners)
    for (const c of l.clients || []) {
      const row = clients.insertRow();
      row.dataset.client = c.address + ":" + c.port;
      cell(row, l.name);
      cell(row, c.address + ":" + c.port);
      cell(row, c.connected_s + " s", "num");
      cell(row, age(c.idle_ms), "num");
      cell(row, c.requests, "num");
      cell(row, c.exceptions, "num");
    }
  for (const l of plant.listeners) {
    const row = body.insertRow();
    cell(row, l.name);
    cell(row, l.clients_connected, "num");
    cell(row, l.clients_accepted, "num");
    cell(row, l.clients_refused, "num");
    cell(row, l.clients_denied, "num");
    cell(row, l.clients_timed_out, "num");
    cell(row, l.framing_errors, "num");
    cell(row, (l.functions || []).map((f) => "fc" + f.function + ": " + f.requests +
                                            " (" + f.exceptions + ")").join(", "));
  }
}

function plot(canvas, samples, now) {
  const w = (canvas.width = canvas.clientWidth * devicePixelRatio);
  const h = (canvas.height = canvas.clientHeight * devicePixelRatio);
  const g = canvas.getContext("2d");
  g.clearRect(0, 0, w, h);
  if (samples.length < 2) return;
  let lo = Infinity, hi = -Infinity;
  for (const [, p] of samples) { lo = Math.min(lo, p); hi = Math.max(hi, p); }
  if (hi === lo) { hi += 1; lo -= 1; }
  const x = (t) => w - ((now - t) / (PLOT_SECONDS * 1000)) * w;
  const y = (p) => h - 4 - ((p - lo) / (hi - lo)) * (h - 8);
  g.strokeStyle = "#2271b1";
  g.lineWidth = 2 * devicePixelRatio;
  g.beginPath();
  samples.forEach(([t, p], i) => (i ? g.lineTo(x(t), y(p)) : g.moveTo(x(t), y(p))));
  g.stroke();
  g.fillStyle = "#646970";
  g.font = 10 * devicePixelRatio + "px sans-serif";
  g.fillText(String(hi), 2, 10 * devicePixelRatio);
  g.fillText(String(lo), 2, h - 2);
}

function renderAxes(plant) {
  const cards = document.getElementById("axis-cards");
  const now = plant.time_ms;
  for (const a of plant.axes) {
    let card = cards.querySelector(`[data-axis="${CSS.escape(a.name)}"]`);
    if (!card) {
      card = document.createElement("div");
      card.className = "axis";
      card.dataset.axis = a.name;
      card.innerHTML = "<h3></h3><dl></dl><canvas></canvas>";
      cards.append(card);
    }
    card.dataset.state = a.state;
    card.querySelector("h3").textContent =
        a.name + " (unit " + a.unit + (a.listener ? ", " + a.listener : "") + ")";
    const fields = [
      ["state", a.state], ["position", a.position], ["velocity", a.velocity],
      ["status", a.status.join(" ")], ["error", a.error_id ? hex(a.error_id) : ""],
      ["command", a.command + " " + a.command_status +
                  (a.command_error ? " (error " + hex(a.command_error) + ")" : "")],
    ];
    const dl = card.querySelector("dl");
    dl.replaceChildren();
    for (const [k, v] of fields) {
      const dt = document.createElement("dt");
      dt.textContent = k;
      const dd = document.createElement("dd");
      dd.textContent = v === null || v === undefined ? "—" : String(v);
      dd.dataset.field = k;
      dl.append(dt, dd);
    }
    const samples = positions.get(a.name) || [];
    if (a.position !== null) samples.push([now, a.position]);
    while (samples.length && samples[0][0] < now - PLOT_SECONDS * 1000) samples.shift();
    positions.set(a.name, samples);
    card.dataset.samples = samples.length;
    plot(card.querySelector("canvas"), samples, now);
  }
}

function metricList(metrics) {
  const dl = document.createElement("dl");
  dl.className = "metrics";
  for (const m of metrics) {
    const dt = document.createElement("dt");
    dt.textContent = m.name;
    const dd = document.createElement("dd");
    dd.textContent = m.value + (m.datatype ? " (" + m.datatype + ")" : "");
    dl.append(dt, dd);
  }
  return dl;
}

function renderFleet(plant) {
  const summary = document.getElementById("fleet-summary");
  const body = document.querySelector("#fleet-nodes tbody");
  const devices = document.getElementById("fleet-devices");
  const f = plant.fleet;
  if (!f) {
    summary.textContent = "Sparkplug is off on this gateway (docs/sparkplug.md): no fleet to show.";
    body.replaceChildren();
    devices.replaceChildren();
    return;
  }
  const hosts = Object.entries(f.hosts).map(([id, s]) => id + ": " + s).join(", ");
  summary.textContent = "group " + f.group + " on " + f.broker + " (" +
      (f.connected ? "connected" : "not connected") + ")" +
      (hosts ? "; primary hosts " + hosts : "") +
      (f.malformed ? "; " + f.malformed + " malformed message(s)" : "");
  body.replaceChildren();
  devices.replaceChildren();
  for (const n of f.edge_nodes) {
    const row = body.insertRow();
    row.dataset.edge = n.name;
    row.dataset.state = n.born ? "born" : "dead";
    cell(row, n.name);
    cell(row, n.born ? "born" : "dead", "state " + (n.born ? "state-online" : "state-offline"));
    cell(row, n.bd_seq, "num");
    cell(row, n.messages, "num");
    cell(row, n.seq_gaps, "num");
    cell(row, n.devices.filter((d) => d.born).length + " of " + n.devices.length, "num");
    cell(row, n.metrics.length, "num");
    for (const d of n.devices) {
      const details = document.createElement("details");
      details.dataset.device = n.name + "/" + d.name;
      details.dataset.state = d.born ? "born" : "dead";
      const s = document.createElement("summary");
      s.textContent = n.name + "/" + d.name + ": " + (d.born ? "born" : "dead") + ", " +
                      d.metrics.length + " metrics";
      details.append(s, metricList(d.metrics));
      devices.append(details);
    }
  }
}

function traceLine(f) {
  const t = new Date(f.t);
  const stamp = t.toISOString().replace("T", " ").replace("Z", "") +
                String(Math.floor((f.t % 1) * 1000)).padStart(3, "0");
  return `${stamp} ${f.bus} ${f.node} ${f.dir} ${f.outcome} '${f.bytes}'` +
         (f.label ? " " + f.label : "");
}

function traceShown(f) {
  const bus = document.getElementById("trace-bus").value;
  const node = document.getElementById("trace-node").value.trim();
  const outcome = document.getElementById("trace-outcome").value;
  return (!bus || f.bus === bus) && (!node || f.node.includes(node)) &&
         (!outcome || f.outcome === outcome);
}

function renderTrace() {
  const pre = document.getElementById("trace");
  const shown = traceFrames.filter(traceShown);
  pre.textContent = shown.slice(-1000).map(traceLine).join("\n");
  pre.dataset.lines = shown.length;
  pre.scrollTop = pre.scrollHeight;
  document.getElementById("trace-count").textContent =
      shown.length + " of " + traceFrames.length + " frames" + (tracePaused ? " (paused)" : "");
}

function onTrace(event) {
  const t = JSON.parse(event.data);
  for (const f of t.frames) traceFrames.push(f);
  if (t.dropped) traceFrames.push({t: Date.now(), bus: "-", node: "-", dir: "-",
                                   outcome: "-", bytes: t.dropped + " frame(s) not shown"});
  traceFrames.splice(0, Math.max(0, traceFrames.length - TRACE_KEEP));
  if (!tracePaused) renderTrace();
}

function onPlant(event) {
  const plant = JSON.parse(event.data);
  lastPlant = plant;
  document.getElementById("clock").textContent = utcTime(plant.time_ms);
  renderNodes(plant);
  renderBuses(plant);
  renderAxes(plant);
  renderListeners(plant);
  renderFleet(plant);
}

function connect(withTrace) {
  if (source) source.close();
  sourceWithTrace = withTrace;
  source = new EventSource(withToken("/events" + (withTrace ? "?trace=1" : "")));
  const link = document.getElementById("link");
  source.onopen = () => { link.textContent = "live"; link.className = "link up"; };
  source.onerror = () => {
    link.textContent = "reconnecting";
    link.className = "link down";
    // A refusal (no token, a wrong one) is said as the server words it, not retried for ever.
    fetch(withToken("/api/plant")).then((r) => {
      if (r.status !== 403) return;
      source.close();
      r.text().then((t) => { link.textContent = t.trim(); });
    }).catch(() => {});
  };
  source.addEventListener("plant", onPlant);
  source.addEventListener("trace", onTrace);
}

function show(tab) {
  for (const b of document.querySelectorAll("nav button"))
    b.classList.toggle("active", b.dataset.tab === tab);
  for (const s of document.querySelectorAll(".tab")) s.classList.toggle("active", s.id === tab);
  // Frames are taken from the buses only while someone looks at them.
  if ((tab === "bus") !== sourceWithTrace) connect(tab === "bus");
  if (tab === "axes" && lastPlant) renderAxes(lastPlant);
  location.hash = tab;
}

for (const b of document.querySelectorAll("nav button"))
  b.addEventListener("click", () => show(b.dataset.tab));
for (const id of ["trace-bus", "trace-node", "trace-outcome"])
  document.getElementById(id).addEventListener("input", renderTrace);
document.getElementById("trace-pause").addEventListener("click", (e) => {
  tracePaused = !tracePaused;
  e.target.textContent = tracePaused ? "Resume" : "Pause";
  renderTrace();
});
document.getElementById("trace-download").addEventListener("click", () => {
  const text = traceFrames.filter(traceShown).map(traceLine).join("\n") + "\n";
  const a = document.createElement("a");
  a.href = URL.createObjectURL(new Blob([text], {type: "text/plain"}));
  a.download = "fieldgate-trace.txt";
  a.click();
  URL.revokeObjectURL(a.href);
});

const initial = location.hash.slice(1);
connect(initial === "bus");
show(["plant", "axes", "bus", "fleet"].includes(initial) ? initial : "plant");

// cosim watch: polls /api/state (GET; the page never controls the run) and draws
// the progress, the time shares, one uPlot chart per series and the snapshot.
"use strict";
const POLL_MS = 1000;          // the server rebuilds its state at most every 0.5 s
const CHART_W = 460, CHART_H = 220;
// the traction is drawn first, split by unit: forces (N), load (N), sinkage (m)
const TRACTION = "coupler/traction";
const TRACTION_CHARTS = [["T_H", "T_R", "T_P"], ["vertical_load"], ["sinkage"]];
const COLOURS = ["#1b7", "#d42", "#26c", "#e90", "#939", "#099", "#777", "#b60", "#5a2",
                 "#c27"];
const W = window.cosimWatch = {state: null, plots: {}, version: -1};

function fmt(v, digits) {
  return v === null || v === undefined ? "-" : Number(v).toPrecision(digits);
}
function fmtTime(s) {
  if (s === null || s === undefined || !isFinite(s)) return "-";
  s = Math.round(s);
  const h = Math.floor(s / 3600), m = Math.floor(s / 60) % 60, sec = s % 60;
  return (h ? h + " h " : "") + (h || m ? m + " min " : "") + sec + " s";
}
function el(tag, attrs, text) {
  const e = document.createElement(tag);
  for (const k in attrs || {}) e.setAttribute(k, attrs[k]);
  if (text !== undefined) e.textContent = text;
  return e;
}

function showProgress(s) {
  const p = s.progress || {};
  document.getElementById("source").textContent = s.source;
  const st = document.getElementById("status");
  st.textContent = s.status;
  st.className = "badge " + s.status;
  document.getElementById("step").textContent = p.step === undefined ? 0 : p.step;
  document.getElementById("n_steps").textContent = p.n_steps === undefined ? "?" : p.n_steps;
  document.getElementById("t").textContent = fmt(p.t, 6);
  document.getElementById("rate").textContent = fmt(p.steps_per_s, 4);
  document.getElementById("eta").textContent = fmtTime(p.eta_s);
  const frac = p.n_steps ? Math.min(1, p.step / p.n_steps) : 0;
  document.getElementById("progress-bar").style.width = (100 * frac) + "%";
  document.getElementById("error").textContent = s.error || "";
}

function showShares(sh) {
  const body = document.querySelector("#shares tbody");
  body.textContent = "";
  if (!sh.processes) return;
  document.getElementById("shares-note").textContent =
    "sums of the " + sh.rows + " coupler.timing rows received (PROTOCOL.md \"Timing\")";
  for (const [name, p] of Object.entries(sh.processes)) {
    const tr = el("tr", {"data-process": name});
    tr.appendChild(el("td", {}, name));
    for (const q of ["compute", "transfer", "waiting"])
      tr.appendChild(el("td", {"data-part": q}, (100 * p[q]).toFixed(1) + " %"));
    tr.appendChild(el("td", {}, fmt(p.seconds, 4)));
    const bar = el("span", {class: "share"});
    for (const q of ["compute", "transfer", "waiting"]) {
      const seg = el("span", {class: q});
      seg.style.width = (100 * p[q]) + "%";
      bar.appendChild(seg);
    }
    const td = el("td");
    td.appendChild(bar);
    tr.appendChild(td);
    body.appendChild(tr);
  }
}

function chartSpecs(tables) {
  // [id, table key, title, columns]: the traction first, then every table
  const specs = [];
  const tr = tables[TRACTION];
  if (tr) TRACTION_CHARTS.forEach((cols, i) => {
    const have = cols.filter(c => tr.columns.includes(c));
    if (have.length) specs.push([TRACTION + "#" + i, TRACTION, "traction: " + have.join(", "),
                                 have]);
  });
  for (const key of Object.keys(tables).sort())
    specs.push([key, key, key, tables[key].columns.filter(c => c !== "t")]);
  return specs;
}

function chartData(tab, cols) {
  const it = tab.columns.indexOf("t");
  const xs = it >= 0 ? tab.data[it] : tab.index;
  return [xs].concat(cols.map(c => tab.data[tab.columns.indexOf(c)]));
}

function lastRow(box, key, tab) {
  let t = box.querySelector("table.last");
  if (!t) { t = el("table", {class: "last", "data-table": key}); box.appendChild(t); }
  t.textContent = "";
  const head = el("tr"), row = el("tr");
  head.appendChild(el("th", {}, "last row (" + tab.rows + ")"));
  row.appendChild(el("td"));
  tab.columns.forEach((c, j) => {
    head.appendChild(el("th", {}, c));
    const v = tab.last ? tab.last[j] : null;
    row.appendChild(el("td", {"data-col": c}, v === null ? "null" : String(v)));
  });
  t.appendChild(head);
  t.appendChild(row);
}

function showCharts(tables) {
  const root = document.getElementById("charts");
  for (const [id, key, title, cols] of chartSpecs(tables)) {
    const tab = tables[key];
    let w = W.plots[id];
    const sig = tab.columns.join(",");
    if (!w || w.sig !== sig) {
      if (w) { w.plot.destroy(); w.box.remove(); }
      const box = el("div", {class: "chart", "data-chart": id});
      box.appendChild(el("h3", {}, title));
      root.appendChild(box);
      const series = [{label: tab.columns.includes("t") ? "t (s)" : "row"}].concat(
        cols.map((c, i) => ({label: c, stroke: COLOURS[i % COLOURS.length], width: 1.5})));
      const plot = new uPlot({width: CHART_W, height: CHART_H, series: series,
                              scales: {x: {time: false}}}, chartData(tab, cols), box);
      w = W.plots[id] = {plot: plot, box: box, sig: sig, key: key};
    } else {
      w.plot.setData(chartData(tab, cols));
    }
    if (!id.includes("#")) lastRow(w.box, key, tab);
  }
}

function showSnapshot(key) {
  const img = document.getElementById("snapshot");
  if (!key || img.dataset.key === key) return;
  img.dataset.key = key;
  img.src = "/api/snapshot.png?k=" + encodeURIComponent(key);
  img.hidden = false;
  document.getElementById("snap-note").textContent = "snapshots " + key.replace(/,/g, ", ");
}

async function poll() {
  try {
    const r = await fetch("/api/state?v=" + W.version, {cache: "no-store"});
    const s = await r.json();
    if (!s.unchanged && s.version !== W.version) {
      W.state = s;
      W.version = s.version;
      showProgress(s);
      showShares(s.shares);
      showCharts(s.tables);
      showSnapshot(s.snapshot);
    }
  } catch (e) {
    document.getElementById("error").textContent = "cosim watch unreachable: " + e;
  }
  setTimeout(poll, POLL_MS);
}
poll();

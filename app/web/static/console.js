// trajlab console: plain JavaScript over the public /v1 API (no framework, no build step, nothing from the internet).
// The API key (when the service requires one) is asked for once and kept in localStorage; every request
// sends it, which is why the event stream is read with fetch (EventSource cannot send headers).
"use strict";
const Console = (() => {
  const KEY = "trajlab.apiKey";
  const FINAL = ["succeeded", "failed", "cancelled"];
  const $ = (sel) => document.querySelector(sel);
  const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

  class ApiError extends Error {
    constructor(status, message, body) { super(message); this.status = status; this.body = body; }
  }

  function authHeaders(extra) {
    const key = localStorage.getItem(KEY);
    return Object.assign(key ? { Authorization: "Bearer " + key } : {}, extra || {});
  }

  function askKey() {
    const box = $("#key-box");
    if (!box) return;
    box.hidden = false;
    $("#key-form").onsubmit = (e) => {
      e.preventDefault();
      localStorage.setItem(KEY, $("#key-input").value.trim());
      location.reload();
    };
  }

  function showKeyStatus() {
    const el = $("#key-status");
    if (!el || !localStorage.getItem(KEY)) return;
    el.innerHTML = 'API key set <a href="#" id="forget-key">forget</a>';
    $("#forget-key").onclick = (e) => { e.preventDefault(); localStorage.removeItem(KEY); location.reload(); };
  }

  async function api(path, opts = {}) {
    const r = await fetch(path, Object.assign({}, opts, { headers: authHeaders(opts.headers) }));
    if (r.status === 401) { askKey(); throw new ApiError(401, "this service needs an API key", null); }
    if (!r.ok) {
      let body = null;
      try { body = await r.json(); } catch (e) { /* not JSON */ }
      let msg = body && (body.message || body.detail);
      if (typeof msg !== "string") msg = msg ? JSON.stringify(msg) : r.statusText;
      throw new ApiError(r.status, msg, body);
    }
    return r;
  }
  const getJSON = async (path) => (await api(path)).json();

  // Server-Sent Events over fetch; resumes with Last-Event-ID after a dropped connection.
  async function follow(path, onEvent) {
    let last = null;
    for (;;) {
      try {
        const r = await api(path, { headers: last ? { "Last-Event-ID": last } : {} });
        const reader = r.body.getReader();
        const dec = new TextDecoder();
        let buf = "", ev = {};
        for (;;) {
          const { value, done } = await reader.read();
          if (done) break;
          buf += dec.decode(value, { stream: true });
          let i;
          while ((i = buf.indexOf("\n")) >= 0) {
            const line = buf.slice(0, i).replace(/\r$/, "");
            buf = buf.slice(i + 1);
            if (line === "") {
              if (ev.data !== undefined) {
                const e = { event: ev.event || "message", id: ev.id, data: JSON.parse(ev.data) };
                if (e.id) last = e.id;
                onEvent(e);
                if (e.event === "end") return e;
              }
              ev = {};
            } else if (line[0] !== ":") {
              const j = line.indexOf(":");
              const field = j < 0 ? line : line.slice(0, j);
              let v = j < 0 ? "" : line.slice(j + 1);
              if (v[0] === " ") v = v.slice(1);
              if (field === "data") ev.data = ev.data === undefined ? v : ev.data + "\n" + v;
              else ev[field] = v;
            }
          }
        }
      } catch (e) {
        if (e instanceof ApiError) throw e;
      }
      await sleep(2000);
    }
  }

  function text(el, value) { if (el) el.textContent = value == null ? "" : String(value); }
  function pct(p) { return (100 * (p || 0)).toFixed(1) + "%"; }
  function fmt(v) { return typeof v === "number" ? (Number.isInteger(v) ? String(v) : v.toPrecision(7)) : String(v); }

  async function blobUrl(path) { return URL.createObjectURL(await (await api(path)).blob()); }

  // ---- job list ----------------------------------------------------------------------------------
  async function jobList() {
    showKeyStatus();
    const limit = 20;
    let offset = 0;
    const selected = new Set();
    const headlines = new Map();
    const form = $("#filters");
    async function render() {
      const q = new URLSearchParams({ limit, offset });
      for (const name of ["kind", "status"]) if (form[name].value) q.set(name, form[name].value);
      let page;
      try { page = await getJSON("/v1/jobs?" + q); } catch (e) { text($("#page-info"), e.message); return; }
      const body = $("#jobs tbody");
      body.innerHTML = "";
      for (const job of page.items) {
        const tr = document.createElement("tr");
        tr.dataset.id = job.id;
        tr.innerHTML = `<td><input type="checkbox" class="pick"></td><td><a href="/jobs/${job.id}"><code>${job.id.slice(0, 8)}</code></a></td>
          <td>${job.kind}</td><td class="preset"></td><td class="label"></td><td class="status status-${job.status}">${job.status}</td>
          <td><div class="progress"><div class="bar"></div></div></td>
          <td class="headline"></td><td class="message"></td><td>${new Date(job.created_at).toLocaleString()}</td>`;
        tr.querySelector(".bar").style.width = pct(job.progress);  // CSSOM: the CSP allows no style attribute
        text(tr.querySelector(".preset"), job.preset);
        text(tr.querySelector(".label"), job.label);
        text(tr.querySelector(".message"), job.message);
        text(tr.querySelector(".headline"), headlines.get(job.id));
        const box = tr.querySelector(".pick");
        box.checked = selected.has(job.id);
        box.onchange = () => (box.checked ? selected.add(job.id) : selected.delete(job.id));
        body.appendChild(tr);
      }
      // the first headline of each succeeded job (a succeeded result never changes: fetched once per job)
      const missing = page.items.filter((j) => j.status === "succeeded" && !headlines.has(j.id)).map((j) => j.id);
      if (missing.length) {
        try {
          const got = await getJSON("/console/headlines?ids=" + missing.join(","));
          for (const id of missing) headlines.set(id, got[id] || "");
          for (const tr of body.children) text(tr.querySelector(".headline"), headlines.get(tr.dataset.id));
        } catch (e) { /* the column stays empty */ }
      }
      text($("#page-info"), `${page.total ? offset + 1 : 0}-${offset + page.items.length} of ${page.total}`);
      $("#prev").disabled = offset === 0;
      $("#next").disabled = offset + limit >= page.total;
    }
    form.onchange = () => { offset = 0; render(); };
    $("#prev").onclick = () => { offset = Math.max(0, offset - limit); render(); };
    $("#next").onclick = () => { offset += limit; render(); };
    $("#compare-selected").onclick = () => { location.href = "/compare?ids=" + [...selected].join(","); };
    for (;;) { await render(); await sleep(2000); }  // live progress of every row on the page
  }

  // ---- new job: a form generated from the resolved parameters -------------------------------------
  function buildFields(container, obj, path) {
    for (const [key, value] of Object.entries(obj)) {
      const p = path ? path + "." + key : key;
      if (value !== null && typeof value === "object" && !Array.isArray(value)) {
        const fs = document.createElement("fieldset");
        const lg = document.createElement("legend");
        lg.textContent = key;
        fs.appendChild(lg);
        buildFields(fs, value, p);
        container.appendChild(fs);
        continue;
      }
      const row = document.createElement("div");
      row.className = "field";
      const label = document.createElement("label");
      label.textContent = p;
      const input = document.createElement("input");
      input.dataset.path = p;
      input.name = p;
      if (typeof value === "boolean") { input.type = "checkbox"; input.checked = value; input.dataset.type = "bool"; }
      else if (typeof value === "number") { input.value = String(value); input.dataset.type = "number"; }
      else if (typeof value === "string") { input.value = value; input.dataset.type = "string"; }
      else { input.value = value === null ? "" : JSON.stringify(value); input.placeholder = value === null ? "null" : ""; input.dataset.type = "json"; }
      input.size = 40;
      label.htmlFor = input.id = "f-" + p;
      const err = document.createElement("span");
      err.className = "field-error";
      err.dataset.errorFor = p;
      row.append(label, input, err);
      container.appendChild(row);
    }
  }

  function collect(container) {
    const out = {};
    for (const input of container.querySelectorAll("input[data-path]")) {
      const raw = input.value;
      let v;
      if (input.dataset.type === "bool") v = input.checked;
      else if (input.dataset.type === "string") v = raw;
      else if (raw.trim() === "") v = null;
      else if (input.dataset.type === "number") v = Number.isFinite(Number(raw)) ? Number(raw) : raw;
      else { try { v = JSON.parse(raw); } catch (e) { v = raw; } }
      let node = out;
      const parts = input.dataset.path.split(".");
      for (const part of parts.slice(0, -1)) node = node[part] = node[part] || {};
      node[parts[parts.length - 1]] = v;
    }
    return out;
  }

  function setByPath(obj, path, value) {
    const parts = path.split(".");
    let node = obj;
    for (const part of parts.slice(0, -1)) node = node[part] = node[part] || {};
    node[parts[parts.length - 1]] = value;
  }

  function clearErrors() {
    for (const el of document.querySelectorAll(".field-error")) el.textContent = "";
    for (const el of document.querySelectorAll("input.invalid")) el.classList.remove("invalid");
    text($("#form-error"), "");
  }

  // A 422's errors placed next to the field they name; the rest (model-level rules) above the form.
  function showErrors(kind, err) {
    const loose = [];
    const detail = (err.body && Array.isArray(err.body.detail)) ? err.body.detail : [];
    for (const d of detail) {
      let loc = (d.loc || []).map(String);
      if (loc[0] === "body") loc = loc.slice(1);
      if (loc[0] === kind) loc = loc.slice(1);
      if (loc[0] === "params") loc = loc.slice(1);
      let path = loc.join(".");
      let slot = path && document.querySelector(`[data-error-for="${CSS.escape(path)}"]`);
      if (!slot) {  // a rule across fields names them in its message: put it next to the first one named
        for (const el of document.querySelectorAll("[data-error-for]")) {
          if ((d.msg || "").includes(el.dataset.errorFor)) { slot = el; path = el.dataset.errorFor; break; }
        }
      }
      if (slot) {
        slot.textContent = d.msg;
        const input = document.querySelector(`input[data-path="${CSS.escape(path)}"]`);
        if (input) input.classList.add("invalid");
      } else loose.push((path ? path + ": " : "") + d.msg);
    }
    text($("#form-error"), loose.length ? loose.join("\n") : (detail.length ? "" : err.message));
  }

  // ---- new job for a kind whose parameters are a document (KindSpec.json_editor): a JSON editor -----
  // JSON.stringify(value, null, 2), plus the line of every path ("dynamics.v", "states.2.final").
  function pretty(value) {
    const lines = [], at = {};
    function emit(v, path, indent, prefix, suffix) {
      at[path] = lines.length;
      const pad = "  ".repeat(indent);
      if (v !== null && typeof v === "object") {
        const list = Array.isArray(v);
        const entries = list ? v.map((x, i) => [i, x]) : Object.entries(v);
        const [open, close] = list ? ["[", "]"] : ["{", "}"];
        if (!entries.length) { lines.push(pad + prefix + open + close + suffix); return; }
        lines.push(pad + prefix + open);
        entries.forEach(([k, x], i) => emit(x, path === "" ? String(k) : path + "." + k, indent + 1,
                                            list ? "" : JSON.stringify(k) + ": ", i < entries.length - 1 ? "," : ""));
        lines.push(pad + close + suffix);
      } else lines.push(pad + prefix + JSON.stringify(v) + suffix);
    }
    emit(value, "", 0, "", "");
    return { text: lines.join("\n"), at };
  }

  function selectLine(area, line) {
    const lines = area.value.split("\n");
    const start = lines.slice(0, line).reduce((n, l) => n + l.length + 1, 0);
    area.focus();
    area.setSelectionRange(start, start + (lines[line] || "").length);
    area.scrollTop = Math.max(0, line - 5) * (area.scrollHeight / Math.max(1, lines.length));
  }

  // Each 422 under the editor, with the line of the field it names (or of its nearest named parent).
  function showJsonErrors(kind, err, at) {
    const list = $("#json-errors"), area = $("#params-json");
    list.innerHTML = "";
    const detail = (err.body && Array.isArray(err.body.detail)) ? err.body.detail : [];
    let first = null;
    for (const d of detail) {
      let loc = (d.loc || []).map(String);
      if (loc[0] === "body") loc = loc.slice(1);
      if (loc[0] === kind) loc = loc.slice(1);
      if (loc[0] === "params") loc = loc.slice(1);
      let n = loc.length;
      while (n > 0 && at[loc.slice(0, n).join(".")] === undefined) n--;
      const line = n > 0 ? at[loc.slice(0, n).join(".")] : null;
      const li = document.createElement("li");
      const code = document.createElement("code");
      code.textContent = "params" + (loc.length ? "." + loc.join(".") : "");
      li.append(code, document.createTextNode((line !== null ? ` (line ${line + 1})` : "") + ": " + (d.msg || "")));
      if (line !== null) {
        li.onclick = () => selectLine(area, line);
        if (first === null) first = line;
      }
      list.appendChild(li);
    }
    if (!detail.length) text($("#form-error"), err.message);
    if (first !== null) selectLine(area, first);
  }

  async function newJob() {
    showKeyStatus();
    const { presets, kinds, warmFields } = window.TRAJLAB;
    const kindSel = $("#kind"), presetSel = $("#preset"), params = $("#params");
    const q = new URLSearchParams(location.search);
    function fillPresets() {
      presetSel.innerHTML = "";
      for (const name of kinds[kindSel.value].presets) presetSel.add(new Option(name, name));
    }
    const area = $("#params-json");
    let at = {};
    const isJson = () => Boolean(kinds[kindSel.value] && kinds[kindSel.value].json);
    async function showParams(values) {  // a form of fields, or the JSON editor for a document kind
      params.innerHTML = "";
      $("#json-errors").innerHTML = "";
      $("#json-editor").hidden = !isJson();
      params.hidden = isJson();
      if (isJson()) ({ text: area.value, at } = pretty(values));
      else if (window.TrajlabForm) await TrajlabForm.build(params, kindSel.value, values);  // from the schema (form.js)
      else buildFields(params, values, "");
    }
    async function loadPreset() {
      clearErrors();
      text($("#preset-description"), presets[presetSel.value] ? presets[presetSel.value].description : "");
      const p = await getJSON("/v1/presets/" + encodeURIComponent(presetSel.value));
      await showParams(p.params);
    }
    kindSel.onchange = async () => { fillPresets(); await loadPreset(); };
    presetSel.onchange = loadPreset;
    if (q.get("from")) {  // re-run or warm start from a stored job
      const job = await getJSON("/v1/jobs/" + encodeURIComponent(q.get("from")));
      kindSel.value = job.kind;
      fillPresets();
      if (job.preset) presetSel.value = job.preset;
      text($("#preset-description"), presets[presetSel.value] ? presets[presetSel.value].description : "");
      const p = JSON.parse(JSON.stringify(job.params));
      if (q.get("warm") && warmFields[job.kind]) setByPath(p, warmFields[job.kind], job.id);
      await showParams(p);
      $("#label").value = job.label || "";
    } else {
      if (q.get("kind") && kinds[q.get("kind")]) kindSel.value = q.get("kind");
      fillPresets();
      await loadPreset();
    }
    $("#new-job").onsubmit = async (e) => {
      e.preventDefault();
      clearErrors();
      let body;
      if (isJson()) {
        $("#json-errors").innerHTML = "";
        let values;
        try { values = JSON.parse(area.value); } catch (e) { text($("#form-error"), "params: not valid JSON: " + e.message); return; }
        ({ text: area.value, at } = pretty(values));  // one layout, so each error's line is known
        // the text is the whole problem: no preset under it (a deep merge would bring back what was deleted)
        body = { kind: kindSel.value, params: values };
      } else {
        const wrong = window.TrajlabForm ? TrajlabForm.check(params) : [];  // numbers checked before submit
        if (wrong.length) { showErrors(kindSel.value, { body: { detail: wrong.map((w) => ({ loc: w.path.split("."), msg: w.msg })) } }); return; }
        body = { kind: kindSel.value, params: window.TrajlabForm ? TrajlabForm.collect(params) : collect(params) };
        if (presetSel.value) body.preset = presetSel.value;
      }
      if ($("#label").value) body.label = $("#label").value;
      try {
        const job = await (await api("/v1/jobs", { method: "POST", body: JSON.stringify(body),
                                                    headers: { "Content-Type": "application/json" } })).json();
        location.href = "/jobs/" + job.id;
      } catch (err) {
        if (err.status === 422 && isJson()) showJsonErrors(kindSel.value, err, at);
        else if (err.status === 422) showErrors(kindSel.value, err);
        else text($("#form-error"), err.message);
      }
    };
  }

  // ---- one job ------------------------------------------------------------------------------------
  function showState(d) {
    const st = $("#status");
    st.className = "status status-" + d.status;
    text(st, d.status);
    $("#bar").style.width = pct(d.progress);
    text($("#progress-text"), pct(d.progress));
    // the stage and its round (a kind that announces them): "refinement round 2 / solve"
    text($("#stage"), d.stage ? `stage: ${d.stage.name}` : "");
    const head = d.stage ? `${d.stage.name}: ` : null;   // the message repeats its stage for plain readers
    text($("#message"), head && d.message.startsWith(head) ? d.message.slice(head.length) : d.message);
    $("#cancel").hidden = FINAL.includes(d.status);
    if (d.error) text($("#error"), `${d.error.code}: ${d.error.message}`);
  }

  async function showFinished(job) {
    text($("#params"), JSON.stringify(job.params, null, 2));
    const downloads = $("#downloads");
    downloads.innerHTML = "";
    const numbers = await getJSON(`/console/jobs/${job.id}/numbers`);
    const tbody = $("#numbers tbody");
    tbody.innerHTML = "";
    for (const [name, value] of Object.entries(numbers)) {
      const tr = document.createElement("tr");
      tr.innerHTML = "<td></td><td></td>";
      text(tr.children[0], name);
      text(tr.children[1], fmt(value));
      tbody.appendChild(tr);
    }
    if (job.status !== "succeeded") return;
    const result = await getJSON(`/v1/jobs/${job.id}/result`);
    text($("#result"), JSON.stringify(result, null, 2).slice(0, 200000));
    addDownload(`/v1/jobs/${job.id}/result`, "result.json", "result (JSON)");
    let index = null;
    try { index = await getJSON(`/v1/jobs/${job.id}/plots`); } catch (e) { return; }  // no plots for this job
    const plots = $("#plots");
    plots.innerHTML = "<h2>Plots</h2>";
    for (const p of index.plots || []) {
      const img = document.createElement("img");
      img.alt = img.title = p.title || p.name;
      img.className = "plot";
      plots.appendChild(img);
      blobUrl(p.png || p.url || `/v1/jobs/${job.id}/plots/${p.name}.png`).then((u) => (img.src = u));
    }
    if (index.report) addDownload(index.report, `${job.id}.html`, "report (HTML)");
    for (const t of index.tables || []) addDownload(t.url || t.csv, `${t.name}.csv`, `${t.name} (CSV)`);
    if (index.oem) addDownload(index.oem, `${job.id}.oem`, "ephemeris (CCSDS OEM)");
  }

  function addDownload(path, filename, label) {
    const li = document.createElement("li");
    const a = document.createElement("a");
    a.href = "#";
    a.textContent = label;
    a.onclick = async (e) => {  // fetched with the key, then saved
      e.preventDefault();
      const link = document.createElement("a");
      link.href = await blobUrl(path);
      link.download = filename;
      link.click();
    };
    li.appendChild(a);
    $("#downloads").appendChild(li);
  }

  async function jobPage(id) {
    showKeyStatus();
    let job;
    try { job = await getJSON("/v1/jobs/" + encodeURIComponent(id)); }
    catch (e) { text($("#error"), e.message); return; }
    text($("#kind"), job.kind);
    text($("#label"), job.label || "");
    showState(job);
    $("#cancel").onclick = async () => { await api(`/v1/jobs/${id}/cancel`, { method: "POST" }); };
    $("#rerun").onclick = () => { location.href = "/new?from=" + id; };
    $("#delete").onclick = async () => {
      if (!confirm("Delete this job and its result? A running job is cancelled first. This cannot be undone.")) return;
      try { await api(`/v1/jobs/${id}`, { method: "DELETE" }); location.href = "/"; }
      catch (e) { text($("#error"), e.message); }
    };
    text($("#params"), JSON.stringify(job.params, null, 2));
    if (!FINAL.includes(job.status)) await follow(`/v1/jobs/${id}/events`, (e) => showState(e.data));
    job = await getJSON("/v1/jobs/" + encodeURIComponent(id));
    showState(job);
    // only a succeeded job can be a warm start (the API refuses any other with a 422)
    if (window.TRAJLAB.warmFields[job.kind] && job.status === "succeeded") {
      $("#warm").hidden = false;
      $("#warm").onclick = () => { location.href = `/new?from=${id}&warm=1`; };
    }
    await showFinished(job);
  }

  // ---- compare ------------------------------------------------------------------------------------
  async function compare() {
    showKeyStatus();
    const img = $("#compare-img");
    async function show() {
      text($("#compare-error"), "");
      const ids = $("#ids").value.split(/[\s,]+/).filter(Boolean).join(",");
      if (!ids) return;
      try { img.src = await blobUrl("/console/compare.png?ids=" + encodeURIComponent(ids)); img.hidden = false; }
      catch (e) { img.hidden = true; text($("#compare-error"), e.message); }
    }
    $("#compare-form").onsubmit = (e) => { e.preventDefault(); show(); };
    await show();
  }

  return { jobList, newJob, jobPage, compare, api, follow };
})();

// The pages carry no inline script (the Content-Security-Policy allows scripts by path only): what they
// hand over is JSON in <script type="application/json"> blocks, read here (this file is deferred, so
// the document is parsed), and #page-init names the page's entry point.
(() => {
  const data = (id) => { const el = document.getElementById(id); return el ? JSON.parse(el.textContent) : null; };
  window.TRAJLAB = Object.assign(data("trajlab-data") || {}, { presets: data("trajlab-presets") || {} });
  const init = data("page-init");
  if (init) document.addEventListener("DOMContentLoaded", () => Console[init.page](...init.args));
})();

// trajlab console, the Studies pages (/studies, /studies/{id}): plain JavaScript over /v1/studies, using
// console.js's Console.api (the API key, error messages). Loaded after console.js (both deferred, in order).
"use strict";
(() => {
  const $ = (sel) => document.querySelector(sel);
  const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
  const text = (el, v) => { if (el) el.textContent = v == null ? "" : String(v); };
  const pct = (p) => (100 * (p || 0)).toFixed(1) + "%";
  const fmt = (v) => (typeof v === "number" ? (Number.isInteger(v) ? String(v) : v.toPrecision(6)) : v == null ? "" : String(v));
  const getJSON = async (path) => (await Console.api(path)).json();
  const counts = (s) => Object.entries(s.points_by_status).map(([k, v]) => `${k} ${v}`).join(", ");

  async function list() {
    const presets = JSON.parse($("#study-presets").textContent);
    const pick = $("#study-preset");
    const describe = () => text($("#study-preset-description"), (presets[pick.value] || {}).description);
    pick.onchange = describe;
    describe();
    $("#study-form").onsubmit = async (e) => {
      e.preventDefault();
      text($("#study-submit-error"), "");
      try {
        const r = await Console.api("/v1/studies", { method: "POST", headers: { "Content-Type": "application/json" },
                                                     body: JSON.stringify({ study_preset: pick.value }) });
        location.href = "/studies/" + (await r.json()).id;
      } catch (err) { text($("#study-submit-error"), err.message); }
    };
    for (;;) {
      let studies = [];
      try { studies = await getJSON("/v1/studies?limit=50"); } catch (err) { text($("#study-submit-error"), err.message); }
      const body = $("#studies tbody");
      body.innerHTML = "";
      for (const s of studies) {
        const tr = document.createElement("tr");
        tr.innerHTML = `<td><a href="/studies/${s.id}"><code>${s.id.slice(0, 8)}</code></a></td><td class="k"></td>
          <td class="m"></td><td class="l"></td><td class="status status-${s.status}"></td>
          <td><div class="progress"><div class="bar"></div></div></td><td class="c"></td><td class="t"></td>`;
        text(tr.querySelector(".k"), s.kind);
        text(tr.querySelector(".m"), s.mode);
        text(tr.querySelector(".l"), s.label || s.preset);
        text(tr.querySelector(".status"), s.status);
        tr.querySelector(".bar").style.width = pct(s.progress);
        text(tr.querySelector(".c"), `${s.points}: ${counts(s)}`);
        text(tr.querySelector(".t"), s.created_at ? new Date(s.created_at).toLocaleString() : "");
        body.appendChild(tr);
      }
      await sleep(2000);
    }
  }

  function rowsTable(rows) {
    const skip = new Set(["index"]);
    const cols = [...new Set(rows.flatMap((r) => Object.keys(r)))].filter((c) => !skip.has(c));
    $("#study-rows thead").innerHTML = "<tr>" + cols.map(() => "<th></th>").join("") + "</tr>";
    $("#study-rows thead").querySelectorAll("th").forEach((th, i) => text(th, cols[i]));
    const body = $("#study-rows tbody");
    body.innerHTML = "";
    for (const r of rows) {
      const tr = document.createElement("tr");
      tr.dataset.index = r.index;
      for (const c of cols) {
        const td = document.createElement("td");
        if ((c === "job_id" || c === "warm_start_from") && r[c]) {
          const a = document.createElement("a");
          a.href = "/jobs/" + r[c];
          a.className = c === "job_id" ? "point-job" : "";
          text(a, r[c].slice(0, 8));
          td.appendChild(a);
        } else {
          text(td, fmt(r[c]));
          if (c === "status") td.className = "status status-" + r[c];
        }
        tr.appendChild(td);
      }
      body.appendChild(tr);
    }
  }

  async function page(id) {
    let shown = null;  // the points' statuses last drawn: the plot and table are fetched again when they change
    $("#study-cancel").onclick = async () => { await Console.api(`/v1/studies/${id}/cancel`, { method: "POST" }); };
    for (;;) {
      let s;
      try { s = await getJSON("/v1/studies/" + encodeURIComponent(id)); }
      catch (err) { text($("#study-error"), err.message); return; }
      text($("#study-kind"), s.kind);
      text($("#study-mode"), s.mode);
      text($("#study-label"), s.label || s.preset || "");
      text($("#study-status"), s.status);
      $("#study-status").className = "status status-" + s.status;
      $("#study-bar").style.width = pct(s.progress);
      text($("#study-progress"), pct(s.progress));
      text($("#study-counts"), `${s.points} points: ${counts(s)}`);
      $("#study-cancel").hidden = s.status !== "running";
      text($("#study-spec"), JSON.stringify({ sweeps: s.sweeps, base_params: s.base_params }, null, 2));
      const key = JSON.stringify(s.points_by_status);
      if (key !== shown) {
        shown = key;
        try {
          rowsTable((await getJSON(`/v1/studies/${id}/result`)).rows);
          const img = $("#study-plot");
          const old = img.src;
          img.src = URL.createObjectURL(await (await Console.api(`/v1/studies/${id}/plot.png`)).blob());
          img.hidden = false;
          if (old) URL.revokeObjectURL(old);
        } catch (err) { text($("#study-error"), err.message); }
      }
      if (s.status !== "running") { $("#study-plot").dataset.final = "1"; return; }
      await sleep(1500);
    }
  }

  document.addEventListener("DOMContentLoaded", () => {
    const init = document.getElementById("study-init");
    if (init) page(JSON.parse(init.textContent));
    else if (document.getElementById("studies")) list();
  });
})();

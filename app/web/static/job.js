// trajlab console, the job page's reading aids (issue 28): the kind's headline numbers with their units
// and verdicts, a failed job explained (what went wrong, where, what to try) with its last iterate's
// plots, wide plots at full width and any plot full size on click, and the sections a kind's results fill
// (its KindSpec.console_extras, in the page's kinds data): "front_table", the table of Pareto-front points
// with the point the OEM download uses.  Uses console.js's Console.api; loaded after it (both deferred, in
// order).  Data from /console/jobs/{id}/summary and the public /v1 routes.
"use strict";
(() => {
  const $ = (sel) => document.querySelector(sel);
  const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
  const FINAL = ["succeeded", "failed", "cancelled"];
  const getJSON = async (path) => (await Console.api(path)).json();
  const el = (tag, cls, textValue) => {
    const e = document.createElement(tag);
    if (cls) e.className = cls;
    if (textValue != null) e.textContent = String(textValue);
    return e;
  };
  const num = (v, digits = 6) => (typeof v === "number" ? (Number.isInteger(v) ? String(v) : v.toPrecision(digits)) : "");

  // The job page's sections a kind's results fill (KindSpec.console_extras; console.js reads the page's data).
  const extras = (kind) => (((window.TRAJLAB || {}).kinds || {})[kind] || {}).extras || [];

  async function saveAs(path, filename) {  // fetched with the key, then saved
    const link = document.createElement("a");
    link.href = URL.createObjectURL(await (await Console.api(path)).blob());
    link.download = filename;
    link.click();
  }

  function showHeadlines(lines) {
    const list = $("#headlines");
    list.innerHTML = "";
    for (const h of lines) {
      const li = el("li", h.good === true ? "good" : h.good === false ? "bad" : "", h.text);
      li.dataset.name = h.name;
      list.appendChild(li);
    }
    list.hidden = !lines.length;
  }

  async function showFailure(id, f, plots) {
    const box = $("#failure");
    box.hidden = false;
    $("#error").hidden = true;  // the section below says it all, in more words
    $("#numbers-section").hidden = true;  // a failed job has no key numbers: no empty heading
    $("#failure-code").textContent = f.code;
    $("#failure-what").textContent = f.what;
    $("#failure-message").textContent = f.message;
    $("#failure-proved").hidden = !f.proved;
    $("#failure-where").textContent = f.where ? "Where: " + f.where + "." : "";
    const advice = $("#failure-advice");
    advice.innerHTML = "";
    for (const a of f.advice) advice.appendChild(el("li", "", a));
    const where = $("#failure-plots");
    where.innerHTML = "";
    if (plots.length) where.appendChild(el("h3", "", "The last iterate (where the solver stopped)"));
    for (const p of plots) {
      const img = el("img", "plot");
      img.alt = img.title = p.title + " (last iterate)";
      where.appendChild(img);
      Console.api(p.png).then(async (r) => { img.src = URL.createObjectURL(await r.blob()); })
        .catch(() => img.remove());  // a plot the last iterate cannot fill
    }
  }

  // The "front_table" extra: one row per Pareto-front point, a choice of point for the OEM download.
  async function frontTable(id, job) {
    const result = await getJSON(`/v1/jobs/${id}/result`);
    const front = result.pareto_front || [];
    if (!front.length) return;
    const box = $("#front");
    box.hidden = false;
    const order = front.map((p, i) => i).sort((a, b) => (front[a].delta_v_mps ?? Infinity) - (front[b].delta_v_mps ?? Infinity));
    let chosen = order[0];
    const tbody = $("#front-table tbody");
    tbody.innerHTML = "";
    for (const i of order) {
      const p = front[i];
      const tr = document.createElement("tr");
      const pick = el("input");
      pick.type = "radio";
      pick.name = "front-point";
      pick.value = String(i);
      pick.checked = i === chosen;
      pick.onchange = () => { chosen = i; $("#front-chosen").textContent = String(i); };
      const cells = [pick, el("span", "", i), el("span", "", num(p.delta_v_mps)), el("span", "", num(p.position_error_m)),
                     el("span", "", num(p.velocity_error_mps)), el("span", "", (p.times_s || []).map((t) => num(t, 5)).join(", "))];
      for (const c of cells) { const td = document.createElement("td"); td.appendChild(c); tr.appendChild(td); }
      tbody.appendChild(tr);
    }
    $("#front-chosen").textContent = String(chosen);
    $("#front-oem").onclick = (e) => { e.preventDefault(); saveAs(`/v1/jobs/${id}/result.oem?point=${chosen}`, `${id}-point-${chosen}.oem`); };
    $("#front-csv").onclick = (e) => { e.preventDefault(); saveAs(`/v1/jobs/${id}/result.csv?table=pareto_front`, `${id}-front.csv`); };
  }

  // Wide figures (several panels side by side) take the page's width; a click opens any plot full size.
  function plotsReadable() {
    document.addEventListener("load", (e) => {
      const img = e.target;
      if (img.tagName === "IMG" && img.classList.contains("plot") && img.naturalWidth > 900) img.classList.add("wide");
    }, true);
    document.addEventListener("click", (e) => {
      const img = e.target;
      if (img.tagName !== "IMG" || !img.classList.contains("plot") || !img.src) return;
      const full = $("#plot-full");
      $("#plot-full img").src = img.src;
      $("#plot-full img").alt = img.alt;
      full.hidden = false;
    });
    $("#plot-full").onclick = () => { $("#plot-full").hidden = true; };
    document.addEventListener("keydown", (e) => { if (e.key === "Escape") $("#plot-full").hidden = true; });
  }

  async function page(id) {
    plotsReadable();
    for (;;) {  // the job page's own event stream shows progress; this waits for the end
      let s;
      try { s = await getJSON(`/console/jobs/${id}/summary`); } catch (e) { return; }
      if (FINAL.includes(s.status)) {
        showHeadlines(s.headlines || []);
        if (s.failure) await showFailure(id, s.failure, s.last_iterate_plots || []);
        if (s.status === "succeeded") {
          const job = await getJSON(`/v1/jobs/${id}`);
          if (extras(job.kind).includes("front_table")) await frontTable(id, job);
        }
        document.body.dataset.summary = "shown";  // tests wait for this
        return;
      }
      await sleep(1500);
    }
  }

  document.addEventListener("DOMContentLoaded", () => {
    const init = document.getElementById("page-init");
    const data = init ? JSON.parse(init.textContent) : null;
    if (data && data.page === "jobPage") page(data.args[0]);
  });
})();

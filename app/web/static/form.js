// trajlab console, the New job form generated from the kind's JSON schema (issue 28): each field with its
// description and unit beside it, enumerations as selects, numbers checked against the schema's bounds
// before submit, nullable fields shown as "none", tables (lists of rows) edited as a grid of text, one row
// a line.  console.js's newJob calls TrajlabForm.build / check / collect; the schema comes from
// /console/kinds/{kind}/schema (the parameter model's JSON schema).  Loaded after console.js.
"use strict";
window.TrajlabForm = (() => {
  const schemas = {};
  // Units from the field name's suffix: the API's one naming rule (SI, angles in degrees).
  const SUFFIX_UNITS = [["_kg_m3", "kg/m^3"], ["_m3_s2", "m^3/s^2"], ["_rad_s", "rad/s"], ["_w_m2", "W/m^2"],
    ["_mps2", "m/s^2"], ["_mps", "m/s"], ["_m2", "m^2"], ["_deg", "deg"], ["_km", "km"], ["_kg", "kg"],
    ["_pa", "Pa"], ["_s", "s"], ["_m", "m"]];

  function unitOf(name) {
    const hit = SUFFIX_UNITS.find(([suffix]) => name.endsWith(suffix));
    return hit ? hit[1] : "";
  }

  async function schemaFor(kind) {
    if (!schemas[kind]) schemas[kind] = await (await Console.api(`/console/kinds/${encodeURIComponent(kind)}/schema`)).json();
    return schemas[kind];
  }

  // The field's schema with $ref followed and a nullable union split: {s, nullable}.
  function resolve(root, s, value) {
    let nullable = false;
    const said = s && s.description;  // the field's own description wins over its type's
    for (let guard = 0; s && guard < 10; guard++) {
      if (s.$ref) { s = Object.assign({}, root.$defs[s.$ref.split("/").pop()], said ? { description: said } : {}); continue; }
      const branches = s.anyOf || s.oneOf;
      if (!branches) break;
      const real = branches.filter((b) => b.type !== "null");
      nullable = nullable || real.length < branches.length;
      if (real.length === 1) { s = Object.assign({}, s, real[0], { anyOf: undefined, oneOf: undefined }); continue; }
      if (real.every((b) => b.const !== undefined || b.enum)) {
        s = { enum: real.flatMap((b) => (b.enum ? b.enum : [b.const])), description: s.description };
        break;
      }
      const keys = value && typeof value === "object" && !Array.isArray(value) ? Object.keys(value) : null;
      const picked = keys && real.map((b) => (b.$ref ? root.$defs[b.$ref.split("/").pop()] : b))
        .find((b) => b.properties && keys.every((k) => k in b.properties));
      if (picked) { s = Object.assign({ description: s.description }, picked); continue; }
      return { s: { description: s.description }, nullable };  // a union the form cannot split: JSON
    }
    return { s: s || {}, nullable };
  }

  function describe(row, s, name) {
    const unit = unitOf(name);
    const note = document.createElement("span");
    note.className = "field-help";
    const bits = [];
    if (unit) bits.push(`[${unit}]`);
    if (s.description) bits.push(s.description);
    const range = [];
    if (s.minimum !== undefined) range.push(`>= ${s.minimum}`);
    if (s.exclusiveMinimum !== undefined) range.push(`> ${s.exclusiveMinimum}`);
    if (s.maximum !== undefined) range.push(`<= ${s.maximum}`);
    if (s.exclusiveMaximum !== undefined) range.push(`< ${s.exclusiveMaximum}`);
    if (range.length) bits.push("(" + range.join(", ") + ")");
    note.textContent = bits.join(" ");
    row.appendChild(note);
  }

  const isGrid = (s) => s.type === "array" && s.items && (s.items.type === "array" || (s.items.anyOf || []).some((b) => b.type === "array"));
  const gridText = (rows) => rows.map((r) => (Array.isArray(r) ? r.join("  ") : String(r))).join("\n");

  function leaf(container, root, key, path, value, s, nullable) {
    const row = document.createElement("div");
    row.className = "field";
    const label = document.createElement("label");
    label.textContent = key;
    label.title = path;
    let input;
    if (s.enum) {
      input = document.createElement("select");
      if (nullable) input.add(new Option("none", ""));
      for (const v of s.enum) input.add(new Option(String(v), String(v)));
      input.value = value === null || value === undefined ? "" : String(value);
      input.dataset.type = "enum";
      input.dataset.values = JSON.stringify(s.enum);
    } else if (s.type === "boolean") {
      input = document.createElement("input");
      input.type = "checkbox";
      input.checked = Boolean(value);
      input.dataset.type = "bool";
    } else if (s.type === "number" || s.type === "integer") {
      input = document.createElement("input");
      input.value = value === null || value === undefined ? "" : String(value);
      input.inputMode = "decimal";
      input.dataset.type = "number";
      input.dataset.schema = JSON.stringify({ type: s.type, minimum: s.minimum, maximum: s.maximum,
        exclusiveMinimum: s.exclusiveMinimum, exclusiveMaximum: s.exclusiveMaximum });
      input.size = 16;
    } else if (s.type === "string") {
      input = document.createElement("input");
      input.value = value === null || value === undefined ? "" : String(value);
      input.dataset.type = "string";
      input.size = 30;
    } else if (isGrid(s) && (value === null || (Array.isArray(value) && value.length && value.every((r) => Array.isArray(r) && r.length)))) {
      input = document.createElement("textarea");  // a table: one row a line, values separated by spaces
      input.value = value === null ? "" : gridText(value);
      input.rows = Math.min(16, Math.max(3, (value || []).length + 1));
      input.cols = 60;
      input.className = "grid";
      input.dataset.type = "grid";
    } else {
      input = document.createElement(Array.isArray(value) && JSON.stringify(value).length > 60 ? "textarea" : "input");
      input.value = value === null || value === undefined ? "" : JSON.stringify(value);
      if (input.tagName === "TEXTAREA") { input.rows = 3; input.cols = 60; } else input.size = 30;
      input.dataset.type = "json";
    }
    if (nullable) { input.dataset.nullable = "1"; if ("placeholder" in input) input.placeholder = "none"; }
    input.dataset.path = path;
    input.name = path;
    label.htmlFor = input.id = "f-" + path;
    const err = document.createElement("span");
    err.className = "field-error";
    err.dataset.errorFor = path;
    row.append(label, input);
    describe(row, s, key);
    row.appendChild(err);
    container.appendChild(row);
  }

  function fields(container, root, schema, values, path) {
    for (const [key, value] of Object.entries(values)) {
      const p = path ? path + "." + key : key;
      const prop = (schema && schema.properties && schema.properties[key]) || {};
      const { s, nullable } = resolve(root, prop, value);
      if (value === null && nullable && s.properties) {  // "none" until opened and filled in
        const box = document.createElement("details");
        box.className = "nullable-object";
        box.dataset.objectPath = p;
        const sum = document.createElement("summary");
        sum.textContent = `${key}: none (open to fill in)`;
        box.appendChild(sum);
        if (s.description) { const d = document.createElement("p"); d.className = "field-help"; d.textContent = s.description; box.appendChild(d); }
        const blank = Object.fromEntries(Object.keys(s.properties).map((k) => [k, null]));
        fields(box, root, s, blank, p);
        container.appendChild(box);
      } else if (value !== null && typeof value === "object" && !Array.isArray(value) && s.properties) {
        const fs = document.createElement("fieldset");
        const lg = document.createElement("legend");
        lg.textContent = key;
        fs.appendChild(lg);
        if (s.description) { const d = document.createElement("p"); d.className = "field-help"; d.textContent = s.description; fs.appendChild(d); }
        fields(fs, root, s, value, p);
        container.appendChild(fs);
      } else leaf(container, root, key, p, value, s, nullable);
    }
  }

  async function build(container, kind, values) {
    const root = await schemaFor(kind);
    container.innerHTML = "";
    fields(container, root, root, values, "");
  }

  function parseGrid(raw) {
    return raw.trim().split(/\n+/).map((line) => line.trim().split(/[\s,;]+/).filter(Boolean).map(Number));
  }

  const blank = (input) => (input.dataset.type === "bool" ? !input.checked : (input.value || "").trim() === "");
  // A "none" object nobody filled in: every field in it left empty.
  const untouched = (box) => [...box.querySelectorAll("[data-path]")].every(blank);

  // The numbers checked before submit: [{path, msg}]; the service checks everything again.
  function check(container) {
    const errors = [];
    const skip = new Set([...container.querySelectorAll("details.nullable-object")].filter(untouched)
      .flatMap((box) => [...box.querySelectorAll("[data-path]")]));
    for (const input of container.querySelectorAll("[data-path]")) {
      if (skip.has(input)) continue;
      const raw = (input.value || "").trim();
      const path = input.dataset.path;
      if (raw === "") {
        if (!input.dataset.nullable && ["number", "grid"].includes(input.dataset.type)) errors.push({ path, msg: "a value is required" });
        continue;
      }
      if (input.dataset.type === "number") {
        const v = Number(raw), s = JSON.parse(input.dataset.schema);
        if (!Number.isFinite(v)) errors.push({ path, msg: `not a number: ${raw}` });
        else if (s.type === "integer" && !Number.isInteger(v)) errors.push({ path, msg: "Input should be a whole number (checked before sending)" });
        else if (s.minimum !== undefined && v < s.minimum) errors.push({ path, msg: `Input should be greater than or equal to ${s.minimum} (checked before sending)` });
        else if (s.exclusiveMinimum !== undefined && v <= s.exclusiveMinimum) errors.push({ path, msg: `Input should be greater than ${s.exclusiveMinimum} (checked before sending)` });
        else if (s.maximum !== undefined && v > s.maximum) errors.push({ path, msg: `Input should be less than or equal to ${s.maximum} (checked before sending)` });
        else if (s.exclusiveMaximum !== undefined && v >= s.exclusiveMaximum) errors.push({ path, msg: `Input should be less than ${s.exclusiveMaximum} (checked before sending)` });
      } else if (input.dataset.type === "grid") {
        const rows = parseGrid(raw);
        const bad = rows.findIndex((r) => r.some((v) => !Number.isFinite(v)));
        if (bad >= 0) errors.push({ path, msg: `row ${bad + 1}: not all numbers` });  // shapes: the service's rules
      } else if (input.dataset.type === "json") {
        try { JSON.parse(raw); } catch (e) { errors.push({ path, msg: "not valid JSON: " + e.message }); }
      }
    }
    return errors;
  }

  function collect(container) {
    const out = {};
    for (const input of container.querySelectorAll("[data-path]")) {
      const raw = (input.value || "").trim();
      let v;
      const type = input.dataset.type;
      if (type === "bool") v = input.checked;
      else if (raw === "" && (input.dataset.nullable || type !== "string")) v = null;
      else if (type === "string") v = input.value;
      else if (type === "enum") v = JSON.parse(input.dataset.values).find((x) => String(x) === input.value);
      else if (type === "number") v = Number(raw);
      else if (type === "grid") v = parseGrid(raw);
      else { try { v = JSON.parse(raw); } catch (e) { v = raw; } }
      let node = out;
      const parts = input.dataset.path.split(".");
      for (const part of parts.slice(0, -1)) node = node[part] = node[part] || {};
      node[parts[parts.length - 1]] = v;
    }
    // outermost last, so a whole untouched "none" object is null whatever its inner ones are
    const boxes = [...container.querySelectorAll("details.nullable-object")].filter(untouched)
      .sort((a, b) => b.dataset.objectPath.length - a.dataset.objectPath.length);
    for (const box of boxes) {
      let node = out;
      const parts = box.dataset.objectPath.split(".");
      for (const part of parts.slice(0, -1)) node = node[part] = node[part] || {};
      node[parts[parts.length - 1]] = null;
    }
    return out;
  }

  return { build, check, collect, unitOf };
})();

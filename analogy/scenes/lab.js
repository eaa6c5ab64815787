// The browser lab (analogy.scenes.lab_page): sliders set the pose, the parameters and the step
// forces; each move writes the netlist again, runs it in ngspice compiled to WebAssembly, and sets
// each joint rate beside the exact solution computed here. modelParts(values) comes before this
// script: M, B and K of the model at (coordinates..., parameters...), generated from its sympy form.
const LAB = JSON.parse(document.getElementById("lab-data").textContent);
const n = LAB.n;

// --- small dense linear algebra -------------------------------------------------------------
const zeros = (r, c) => Array.from({length: r}, () => new Array(c).fill(0));
const eye = (k) => zeros(k, k).map((row, i) => (row[i] = 1, row));
const mul = (a, b) => a.map((row) => b[0].map((_, j) => row.reduce((s, x, k) => s + x * b[k][j], 0)));
const transpose = (a) => a[0].map((_, j) => a.map((row) => row[j]));
const add = (a, b, s = 1) => a.map((row, i) => row.map((x, j) => x + s * b[i][j]));
const scale = (a, s) => a.map((row) => row.map((x) => x * s));
const norm1 = (a) => Math.max(...transpose(a).map((col) => col.reduce((s, x) => s + Math.abs(x), 0)));

function solve(a, b) {
  // Gaussian elimination with partial pivoting: a (k×k) \ b (k×m)
  const k = a.length, m = b[0].length;
  const w = a.map((row, i) => row.concat(b[i]));
  for (let c = 0; c < k; c++) {
    let p = c;
    for (let r = c + 1; r < k; r++) if (Math.abs(w[r][c]) > Math.abs(w[p][c])) p = r;
    [w[c], w[p]] = [w[p], w[c]];
    for (let r = c + 1; r < k; r++) {
      const f = w[r][c] / w[c][c];
      for (let j = c; j < k + m; j++) w[r][j] -= f * w[c][j];
    }
  }
  const x = zeros(k, m);
  for (let r = k - 1; r >= 0; r--)
    for (let j = 0; j < m; j++) {
      let s = w[r][k + j];
      for (let c = r + 1; c < k; c++) s -= w[r][c] * x[c][j];
      x[r][j] = s / w[r][r];
    }
  return x;
}

function expm(a) {
  // scaling and squaring of an 18-term Taylor series: to rounding for ‖A/2^s‖ ≤ 1/2
  const s = Math.max(0, Math.ceil(Math.log2(norm1(a) || 1)) + 1);
  const b = scale(a, 2 ** -s);
  let term = eye(a.length), sum = eye(a.length);
  for (let k = 1; k <= 18; k++) {
    term = scale(mul(term, b), 1 / k);
    sum = add(sum, term);
  }
  for (let k = 0; k < s; k++) sum = mul(sum, sum);
  return sum;
}

// --- the circuit -----------------------------------------------------------------------------
function nodeMatrices(values) {
  const parts = modelParts(values);
  const tinv = LAB.Tinv;
  const node = (x) => (x === null ? null : mul(transpose(tinv), mul(x, tinv)));    // T⁻ᵀ·X·T⁻¹
  return {M: node(parts.M), B: node(parts.B), K: node(parts.K)};
}

function split(x) {
  // grounded x_i = Σ_j X_ij and floating x_ij = −X_ij, zero under zeroTol of their rows' scale
  const rows = x.map((row) => row.reduce((s, v) => s + Math.abs(v), 0));
  const grounded = x.map((row, i) => {
    const g = row.reduce((s, v) => s + v, 0);
    return Math.abs(g) <= LAB.zeroTol * rows[i] ? 0 : g;
  });
  const floating = x.map((row, i) => row.map((v, j) =>
    (i === j || Math.abs(v) <= LAB.zeroTol * Math.sqrt(rows[i]) * Math.sqrt(rows[j])) ? 0 : -v));
  return {grounded, floating};
}

function writeNetlist(matrices, forces) {
  const lines = [`* analogy lab: ${LAB.title}`, "* " + describe()];
  for (const [kind, x] of [["C", matrices.M], ["R", matrices.B], ["L", matrices.K]]) {
    if (x === null) continue;
    const {grounded, floating} = split(x);
    const value = (c) => (kind === "C" ? c : 1 / c);
    grounded.forEach((c, i) => { if (c !== 0) lines.push(`${kind}${i + 1} n${i + 1} 0 ${value(c)}`); });
    for (let i = 0; i < n; i++)
      for (let j = i + 1; j < n; j++)
        if (floating[i][j] !== 0) lines.push(`${kind}${i + 1}_${j + 1} n${i + 1} n${j + 1} ${value(floating[i][j])}`);
  }
  for (const s of LAB.sources) {
    const f = s.scale * forces[s.joint - 1];
    if (f !== 0) lines.push(`${s.name} ${s.b ? "n" + s.b : "0"} n${s.a} DC ${f}`);
  }
  return lines.concat(LAB.analysis, [".end"]).join("\n") + "\n";
}

function exactRates(matrices, forces, times) {
  // y' = A·y + c, y = [x; v] (x only with springs), from rest; the step input is constant, so
  // [[A, c], [0, 0]] exponentiated over each of SPICE's steps carries y exactly between its points
  const {M, B, K} = matrices;
  const current = mul(transpose(LAB.Tinv), forces.map((f) => [f]));               // i = T⁻ᵀ·F
  const mb = solve(M, B), mc = solve(M, current);
  const springs = K !== null, k = springs ? 2 * n : n;
  const z = zeros(k + 1, k + 1);
  if (springs) {
    const mk = solve(M, K);
    for (let i = 0; i < n; i++) {
      z[i][n + i] = 1;
      for (let j = 0; j < n; j++) { z[n + i][j] = -mk[i][j]; z[n + i][n + j] = -mb[i][j]; }
      z[n + i][k] = mc[i][0];
    }
  } else {
    for (let i = 0; i < n; i++) {
      for (let j = 0; j < n; j++) z[i][j] = -mb[i][j];
      z[i][k] = mc[i][0];
    }
  }
  let y = zeros(k + 1, 1);
  y[k][0] = 1;
  const out = [];
  let last = 0;
  const cache = new Map();
  for (const t of times) {
    const h = t - last;
    if (h > 0) {
      const key = h.toPrecision(15);
      if (!cache.has(key)) cache.set(key, expm(scale(z, h)));
      y = mul(cache.get(key), y);
    }
    last = t;
    const v = y.slice(springs ? n : 0, springs ? 2 * n : n).map((row) => row[0]);
    out.push(LAB.Tinv.map((row) => row.reduce((s, x, j) => s + x * v[j], 0)));  // r = T⁻¹·v
  }
  return out;
}

// --- the page --------------------------------------------------------------------------------
const sliders = [];
function slider(group, item, label) {
  const row = document.createElement("div");
  const name = document.createElement("label");
  name.textContent = label;
  const input = document.createElement("input");
  Object.assign(input, {type: "range", min: 0, max: 1000, step: 1});
  const shown = document.createElement("span");
  const logarithmic = group === "parameters";
  const fromUnit = (u) => (logarithmic ? item.min * (item.max / item.min) ** u : item.min + (item.max - item.min) * u);
  const toUnit = (x) => (logarithmic ? Math.log(x / item.min) / Math.log(item.max / item.min) : (x - item.min) / (item.max - item.min));
  input.value = Math.round(1000 * toUnit(item.value));
  const entry = {group, item, input, value: item.value};
  input.addEventListener("input", () => {
    entry.value = Number(input.value) === Math.round(1000 * toUnit(item.value)) ? item.value : fromUnit(input.value / 1000);
    shown.textContent = " " + entry.value.toPrecision(4);
    schedule();
  });
  shown.textContent = " " + item.value.toPrecision(4);
  row.append(name, input, shown);
  document.getElementById("sliders").append(row);
  sliders.push(entry);
}

function current() {
  const q = LAB.allCoordinates.slice(), p = Object.assign({}, LAB.allParameters);
  const forces = LAB.forces.map((f) => f.value);
  for (const s of sliders) {
    if (s.group === "coordinates") q[s.item.index] = s.value;
    else if (s.group === "parameters") p[s.item.name] = s.value;
    else forces[s.item.joint - 1] = s.value;
  }
  return {q, p, forces};
}

function describe() {
  const {q, p, forces} = current();
  return `q = (${q.map((x) => x.toPrecision(4)).join(", ")}), ` +
    Object.entries(p).map(([k, v]) => `${k} = ${v.toPrecision(4)}`).join(", ") +
    `, step forces (${forces.map((x) => x.toPrecision(4)).join(", ")})`;
}

function draw(times, spice, exact) {
  const canvas = document.getElementById("plot"), g = canvas.getContext("2d");
  g.clearRect(0, 0, canvas.width, canvas.height);
  const all = exact.flat().concat(spice.flat());
  const top = Math.max(...all.map(Math.abs)) || 1;
  const x = (t) => 50 + (canvas.width - 70) * t / LAB.tStop;
  const y = (r) => canvas.height / 2 - (canvas.height / 2 - 20) * r / top;
  g.strokeStyle = "#999"; g.beginPath(); g.moveTo(50, y(0)); g.lineTo(canvas.width - 20, y(0)); g.stroke();
  g.fillStyle = "#333"; g.font = "12px sans-serif";
  g.fillText(`±${top.toPrecision(3)}`, 2, 20); g.fillText(`t = ${LAB.tStop} s`, canvas.width - 80, y(0) - 6);
  const colours = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b"];
  for (let j = 0; j < n; j++) {
    g.strokeStyle = colours[j]; g.lineWidth = 4; g.globalAlpha = 0.35; g.beginPath();
    times.forEach((t, k) => (k ? g.lineTo : g.moveTo).call(g, x(t), y(exact[k][j]))); g.stroke();
    g.lineWidth = 1.2; g.globalAlpha = 1; g.beginPath();
    times.forEach((t, k) => (k ? g.lineTo : g.moveTo).call(g, x(t), y(spice[k][j]))); g.stroke();
    g.fillText(`${LAB.joints[j]} rate: SPICE (thin) over exact (wide)`, 60, 18 + 15 * j);
  }
}

let sim = null, running = false, again = false;
function schedule() { if (running) again = true; else run(); }

async function run() {
  running = true;
  const started = performance.now();
  const {q, p, forces} = current();
  const values = q.concat(LAB.parametersOrder.map((k) => p[k]));
  const matrices = nodeMatrices(values);
  const text = writeNetlist(matrices, forces);
  document.getElementById("netlist").textContent = text;
  sim.setNetList(text);
  const result = await sim.runSim();
  const times = result.data[0].values;
  const columns = Array.from({length: n}, (_, k) =>
    result.data.find((d) => d.name.toLowerCase() === `v(n${k + 1})`).values);
  const spice = times.map((_, i) => LAB.Tinv.map((row) => row.reduce((s, x, j) => s + x * columns[j][i], 0)));
  const exact = exactRates(matrices, forces, times);
  const errors = Array.from({length: n}, (_, j) => {
    const peak = Math.max(...exact.map((r) => Math.abs(r[j])));
    const worst = Math.max(...exact.map((r, i) => Math.abs(spice[i][j] - r[j])));
    return peak > 0 ? worst / peak : worst;
  });
  draw(times, spice, exact);
  const table = document.getElementById("errors");
  table.innerHTML = "<tr><th>joint</th><th>peak rate (exact)</th><th>SPICE's error / its peak</th><th></th></tr>" +
    errors.map((e, j) => `<tr><td>${LAB.joints[j]}</td><td>${Math.max(...exact.map((r) => Math.abs(r[j]))).toPrecision(4)}</td>` +
      `<td>${e.toExponential(2)}</td><td>${e <= LAB.bound ? "within" : "past"} the bound ${LAB.bound.toExponential()}</td></tr>`).join("");
  const past = errors.some((e) => e > LAB.bound);
  document.getElementById("status").textContent = `ran ${times.length} points in ${(performance.now() - started).toFixed(0)} ms; ` +
    (past ? "an output is past the bound: the step settings were chosen for the scene as given" : "every output within the bound");
  window.lab = {runs: (window.lab ? window.lab.runs : 0) + 1, netlist: text, times, spice, exact, errors, q, p, forces};
  running = false;
  if (again) { again = false; run(); }
}

document.getElementById("title").textContent = LAB.title;
LAB.parametersOrder = Object.keys(LAB.allParameters);
LAB.coordinates.forEach((c) => slider("coordinates", c, c.name + " [pose]"));
LAB.parameters.forEach((c) => slider("parameters", c, c.name));
LAB.forces.forEach((c) => slider("forces", c, `F${c.joint} (step)`));
const source = document.getElementById("engine").textContent;
const {Simulation} = await import(URL.createObjectURL(new Blob([source], {type: "text/javascript"})));
sim = new Simulation();
await sim.start();
run();

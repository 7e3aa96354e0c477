// mechval report: draws the figures (plotly.js, inlined as text before this
// script) when they scroll into view, keeps an engine's traces toggled together in
// all figures of a scenario, filters by engine and verdict, and opens a
// collapsed scenario when a link points into it. Figure data: JSON in
// <script type="application/json">, the formats of reports/plots.py.
"use strict";
(function () {
  const parsed = new Map();
  function figureData(id) {
    if (!parsed.has(id)) parsed.set(id, JSON.parse(document.getElementById(id).textContent));
    return parsed.get(id);
  }

  // Inverse of plots.encode_stream: inflate, low and high byte planes,
  // running sum modulo 2^16. One Uint16Array per scenario, decoded once.
  const streams = new Map();
  async function codeStream(data) {
    if (!streams.has(data)) {
      streams.set(data, (async () => {
        const packed = Uint8Array.from(atob(data.stream), c => c.charCodeAt(0));
        const inflated = new Response(new Blob([packed]).stream().pipeThrough(new DecompressionStream("deflate")));
        const planes = new Uint8Array(await inflated.arrayBuffer());
        const n = planes.length / 2, codes = new Uint16Array(n);
        let sum = 0;
        for (let i = 0; i < n; i++) { sum = (sum + (planes[i] | (planes[n + i] << 8))) & 0xffff; codes[i] = sum; }
        return codes;
      })());
    }
    return streams.get(data);
  }

  // Inverse of plots.linear_codes / log_codes / _Stream.samples.
  function unpack(codes, entry) {
    const [start, count] = entry.codes, part = codes.subarray(start, start + count);
    if (entry.lin) {
      const [lo, hi] = entry.lin, step = (hi - lo) / 65534;
      return Float64Array.from(part, c => c === 65535 ? NaN : lo + c * step);
    }
    if (entry.log) {
      const [lo, hi] = entry.log, step = (hi - lo) / 32766;
      return Float64Array.from(Int16Array.from(part),
        c => c === -32768 ? NaN : c === 0 ? 0 : Math.sign(c) * Math.pow(10, lo + (Math.abs(c) - 1) * step));
    }
    let index = 0;
    return Uint32Array.from(part, gap => (index += gap));
  }

  // One scenario's signals as overlay and error figures: a grid of
  // subplots sharing the time axis, one legend entry per run.
  function signalFigure(data, codes, kind) {
    const [t0, t1, n] = data.t;
    const time = i => t0 + (t1 - t0) * i / (n - 1);
    const full = Float64Array.from({length: n}, (_, i) => time(i));
    const columns = 3, rows = Math.ceil(data.signals.length / columns);
    const traces = [], annotations = [];
    const layout = {
      grid: {rows: rows, columns: columns, pattern: "independent", xgap: 0.12, ygap: 0.35},
      height: 90 + 190 * rows, margin: {l: 60, r: 20, t: 70, b: 40}, showlegend: true,
      legend: {orientation: "h", x: 0, y: 1, yanchor: "top", yref: "container"},
      hovermode: "closest", annotations: annotations,
    };
    data.signals.forEach((signal, k) => {
      const axis = k === 0 ? "" : String(k + 1);
      const xaxis = "x" + axis, yaxis = "y" + axis;
      layout["xaxis" + axis] = k === 0 ? {} : {matches: "x"};
      layout["yaxis" + axis] = kind === "errors" ? {type: "log", exponentformat: "e"} : {exponentformat: "e"};
      annotations.push({text: (kind === "errors" ? "|error| " : "") + signal.name + " [" + signal.unit + "]",
        xref: xaxis + " domain", yref: yaxis + " domain", x: 0.5, y: 1, yanchor: "bottom",
        showarrow: false, font: {size: 12}});
      const reference = unpack(codes, signal.reference.values);
      const refAt = signal.reference.samples ? unpack(codes, signal.reference.samples) : null;
      if (kind === "overlays") {
        traces.push({x: refAt ? Float64Array.from(refAt, time) : full, y: reference, name: "reference",
          legendgroup: "reference", showlegend: k === 0, xaxis: xaxis, yaxis: yaxis, mode: "lines",
          line: {color: "black", width: 2.5}, hovertemplate: "reference %{y:.6g} at t = %{x:.4g} s<extra></extra>"});
      }
      data.runs.forEach(run => {
        const trace = run.traces[signal.name];
        if (!trace) return;
        const error = unpack(codes, trace.error);
        const at = trace.samples ? unpack(codes, trace.samples) : null;
        const x = at ? Float64Array.from(at, time) : full;
        const common = {x: x, name: run.label, legendgroup: run.label, showlegend: k === 0, xaxis: xaxis,
          yaxis: yaxis, mode: "lines", line: {color: run.colour, width: 1.2}};
        if (kind === "overlays") {
          // engine = reference + error, at the samples the trace keeps
          const values = trace.values ? unpack(codes, trace.values) : Float64Array.from(error, (e, i) => reference[i] + e);
          traces.push(Object.assign(common, {y: values,
            hovertemplate: run.label + " %{y:.6g} at t = %{x:.4g} s<extra></extra>"}));
        } else {
          traces.push(Object.assign(common, {y: Float64Array.from(error, e => e === 0 ? NaN : Math.abs(e)),
            hovertemplate: run.label + " |error| %{y:.3g} at t = %{x:.4g} s<extra></extra>"}));
          if (trace.bound !== undefined) {
            traces.push({x: [t0, t1], y: [trace.bound, trace.bound], name: run.label, legendgroup: run.label,
              showlegend: false, xaxis: xaxis, yaxis: yaxis, mode: "lines",
              line: {color: run.colour, width: 1, dash: "dash"},
              hovertemplate: run.label + " bound %{y:.3g}<extra></extra>"});
          }
        }
      });
    });
    return {data: traces, layout: layout};
  }

  // Energy against time (plots.energy_data): per run its energy E and,
  // below on a log axis, its energy drift or balance residual.
  function energyFigure(data, codes) {
    const traces = [];
    data.runs.forEach((run, k) => {
      const [t0, t1, n] = run.t;
      const time = i => t0 + (t1 - t0) * i / (n - 1);
      const at = run.samples ? unpack(codes, run.samples) : Uint32Array.from({length: n}, (_, i) => i);
      const x = Float64Array.from(at, time);
      const common = {x: x, name: run.label, legendgroup: run.label, mode: "lines",
        line: {color: run.colour, width: run.label === "reference" ? 2.5 : 1.2}};
      traces.push(Object.assign({}, common, {y: unpack(codes, run.energy), xaxis: "x", yaxis: "y",
        hovertemplate: run.label + " E %{y:.8g} J at t = %{x:.4g} s<extra></extra>"}));
      traces.push(Object.assign({}, common, {showlegend: false, xaxis: "x2", yaxis: "y2",
        y: Float64Array.from(unpack(codes, run.residual), e => e === 0 ? NaN : Math.abs(e)),
        hovertemplate: run.label + " %{y:.3g} at t = %{x:.4g} s<extra></extra>"}));
    });
    const title = (text, axis) => ({text: text, xref: axis + " domain", yref: "y" + axis.slice(1) + " domain",
      x: 0.5, y: 1, yanchor: "bottom", showarrow: false, font: {size: 12}});
    const residual = data.measure === "energy_drift" ? "energy drift |E − E(t0)| / S" :
      "energy balance |E − E(t0) − W| / S";
    return {data: traces, layout: {
      grid: {rows: 2, columns: 1, pattern: "independent", ygap: 0.3}, height: 520,
      margin: {l: 70, r: 20, t: 60, b: 40}, hovermode: "closest",
      legend: {orientation: "h", x: 0, y: 1, yanchor: "top", yref: "container"},
      xaxis: {}, xaxis2: {matches: "x", title: {text: "t [s]"}}, yaxis: {exponentformat: "e"},
      yaxis2: {type: "log", exponentformat: "e"},
      annotations: [title("energy E = kinetic + potential [J]", "x"), title(residual, "x2")]}};
  }

  async function figureFor(element) {
    const data = figureData(element.dataset.figure);
    const kind = element.dataset.kind;
    if (kind === "plotly") return data;
    const codes = await codeStream(data);
    return kind === "energy" ? energyFigure(data, codes) : signalFigure(data, codes, kind);
  }

  const hiddenEngines = new Set();
  function engineOf(label) { return label.split(" [")[0]; }

  // plotly.js arrives as text (plots.page_scripts); an inline script runs
  // as soon as it is inserted.
  function loadPlotly() {
    if (window.Plotly) return;
    const script = document.createElement("script");
    script.textContent = document.getElementById("plotly-js").textContent;
    document.head.appendChild(script);
  }

  async function draw(element) {
    const figure = await figureFor(element);
    loadPlotly();
    if (element.dataset.group) {
      figure.data.forEach(trace => {
        if (trace.legendgroup && hiddenEngines.has(engineOf(trace.legendgroup))) trace.visible = "legendonly";
      });
    }
    await Plotly.newPlot(element, figure.data, figure.layout, {responsive: true, displaylogo: false});
    if (element.dataset.group) {
      element.on("plotly_legendclick", event => toggleGroup(element, event.data[event.curveNumber].legendgroup));
    }
    element.dataset.drawn = "true";
  }

  // A legend click toggles the run in every figure of the scenario.
  function toggleGroup(element, group) {
    if (!group || group === "reference") return true;
    const trace = element.data.find(t => t.legendgroup === group);
    const show = trace.visible === "legendonly";
    document.querySelectorAll('.plot[data-group="' + element.dataset.group + '"]').forEach(plot => {
      if (plot.data) setGroupVisible(plot, group, show);
    });
    return false;
  }
  function setGroupVisible(plot, group, show) {
    const which = plot.data.map((t, k) => t.legendgroup === group ? k : -1).filter(k => k >= 0);
    if (which.length) Plotly.restyle(plot, {visible: show ? true : "legendonly"}, which);
  }

  const observer = new IntersectionObserver(entries => {
    entries.forEach(entry => {
      if (entry.isIntersecting) { observer.unobserve(entry.target); draw(entry.target); }
    });
  }, {rootMargin: "300px"});

  // Filter: rows, runs and scenarios with no visible record are hidden;
  // an unticked engine's traces are hidden in every figure drawn.
  function applyFilter() {
    const engines = new Set(), verdicts = new Set();
    document.querySelectorAll("#filter input[data-engine]").forEach(box => {
      if (box.checked) { engines.add(box.dataset.engine); hiddenEngines.delete(box.dataset.engine); }
      else hiddenEngines.add(box.dataset.engine);
    });
    document.querySelectorAll("#filter input[data-verdict]").forEach(box => {
      if (box.checked) verdicts.add(box.dataset.verdict);
    });
    document.querySelectorAll("tr[data-verdict]").forEach(row => {
      row.hidden = !(engines.has(row.dataset.engine) && verdicts.has(row.dataset.verdict));
    });
    document.querySelectorAll(".run[data-engine]").forEach(run => {
      run.hidden = !run.querySelector("tr[data-verdict]:not([hidden])");
    });
    document.querySelectorAll("section.scenario").forEach(section => {
      const shown = !!section.querySelector(".run:not([hidden])");
      section.hidden = !shown;
      const entry = document.querySelector('#sidebar a[href="#' + section.id + '"]');
      if (entry) entry.parentElement.hidden = !shown;
    });
    document.querySelectorAll("[data-column-engine]").forEach(cell => {
      cell.hidden = !engines.has(cell.dataset.columnEngine);
    });
    document.querySelectorAll(".plot[data-group]").forEach(plot => {
      if (!plot.data) return;
      new Set(plot.data.map(trace => trace.legendgroup)).forEach(group => {
        if (group && group !== "reference") setGroupVisible(plot, group, !hiddenEngines.has(engineOf(group)));
      });
    });
  }

  // Following a link into a collapsed scenario opens it.
  function open(id) {
    const target = id && document.getElementById(id);
    if (!target) return;
    const details = target.matches("section.scenario") ? target.querySelector("details") : target.closest("details");
    if (details && !details.open) { details.open = true; target.scrollIntoView(); }
  }

  document.addEventListener("DOMContentLoaded", () => {
    document.querySelectorAll(".plot[data-figure]").forEach(plot => observer.observe(plot));
    document.querySelectorAll("#filter input").forEach(box => box.addEventListener("change", applyFilter));
    document.addEventListener("click", event => {
      const link = event.target.closest('a[href^="#"]');
      if (link) open(decodeURIComponent(link.getAttribute("href").slice(1)));
    });
    open(decodeURIComponent(location.hash.slice(1)));
  });
})();

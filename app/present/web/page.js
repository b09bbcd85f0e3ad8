// handeye report: the residual table's sorting, the link between table and 3-D view, the residual
// scale slider and the copy button. Plain ES5, no library but plotly (when the page carries it).
(function () {
  "use strict";
  function data(id) {
    var el = document.getElementById(id);
    return el ? JSON.parse(el.textContent) : null;
  }
  var cell = data("handeye-cell");
  var table = document.getElementById("residual-table");
  var view = document.getElementById("cell3d");
  var slider = document.getElementById("residual-scale");
  var scaleText = document.getElementById("residual-scale-value");
  var pickedText = document.getElementById("picked");
  var scale = cell ? cell.scale : 1;

  var picked = -1, pickedRow = null;

  function numeric(text) {
    var v = parseFloat(text);
    return isNaN(v) ? null : v;
  }

  function sortBy(th) {
    var col = th.cellIndex;
    var num = th.getAttribute("data-num") === "1";
    var asc = th.getAttribute("aria-sort") !== "ascending";
    var body = table.tBodies[0];
    var rows = Array.prototype.slice.call(body.rows);
    rows.sort(function (a, b) {  // empty cells last, whichever the direction
      var x = a.cells[col].getAttribute("data-v"), y = b.cells[col].getAttribute("data-v");
      if (num) { x = numeric(x); y = numeric(y); } else { x = x || null; y = y || null; }
      if (x === null || y === null) { return x === y ? 0 : x === null ? 1 : -1; }
      var d = num ? x - y : (x < y ? -1 : x > y ? 1 : 0);
      return asc ? d : -d;
    });
    rows.forEach(function (r) { body.appendChild(r); });
    Array.prototype.forEach.call(table.tHead.rows[0].cells, function (h) { h.removeAttribute("aria-sort"); });
    th.setAttribute("aria-sort", asc ? "ascending" : "descending");
  }

  function plotted() {
    return !!(window.Plotly && view && cell && view.data);
  }

  function shifted(i) {  // sphere + scale * drawn residual: where sample i's centre is drawn
    var s = cell.sphere[i], e = cell.residual_drawn[i];
    return [s[0] + scale * e[0], s[1] + scale * e[1], s[2] + scale * e[2]];
  }

  function pick(i, quiet) {  // quiet: redraw only, the table does not scroll
    if (!table) { return; }
    if (pickedRow) { pickedRow.className = pickedRow.className.replace(/\s*picked/g, ""); }
    pickedRow = table.querySelector("tbody tr[data-i='" + i + "']");
    if (pickedRow) {
      pickedRow.className += " picked";
      if (!quiet && pickedRow.scrollIntoView) { pickedRow.scrollIntoView({block: "nearest"}); }
    }
    picked = i;
    if (!cell || i < 0) { return; }
    var f = cell.flange2base[i], s = cell.sensor2base[i], m = shifted(i);
    if (pickedText) {
      var e = cell.residual_sensor[i];
      pickedText.textContent = "picked: " + cell.ids[i] + (cell.used[i] ? "" : " (excluded)") + ", residual in the " +
        "sensor frame " + e.map(function (v) { return v.toFixed(4); }).join(", ") + " mm";
    }
    if (plotted()) {
      var pts = [[f[0][3], f[1][3], f[2][3]], [s[0][3], s[1][3], s[2][3]], m];
      Plotly.restyle(view, {x: [pts.map(function (p) { return p[0]; })], y: [pts.map(function (p) { return p[1]; })],
                            z: [pts.map(function (p) { return p[2]; })]}, [cell.traces.selected]);
    }
  }

  function drawn(i, mask) {  // the samples the view draws (view.drawn_samples), used or excluded
    return cell.used[i] === mask && (!cell.drawn || cell.drawn[i]);
  }

  function segments(mask) {
    var x = [], y = [], z = [];
    cell.ids.forEach(function (id, i) {
      if (!drawn(i, mask)) { return; }
      var s = cell.sphere[i], m = shifted(i);
      x.push(s[0], m[0], null); y.push(s[1], m[1], null); z.push(s[2], m[2], null);
    });
    return [x, y, z];
  }

  function markers(mask) {
    var x = [], y = [], z = [];
    cell.ids.forEach(function (id, i) {
      if (!drawn(i, mask)) { return; }
      var m = shifted(i);
      x.push(m[0]); y.push(m[1]); z.push(m[2]);
    });
    return [x, y, z];
  }

  function rescale(value) {
    scale = value;
    var label = "×" + (value < 10 ? value.toFixed(1) : value.toFixed(0));
    if (scaleText) { scaleText.textContent = label; }
    if (!plotted()) { return; }
    var t = cell.traces, u = segments(true), x = segments(false), mu = markers(true), mx = markers(false);
    Plotly.restyle(view, {x: [u[0], x[0], mu[0], mx[0]], y: [u[1], x[1], mu[1], mx[1]], z: [u[2], x[2], mu[2], mx[2]]},
                   [t.residuals, t.residuals_excluded, t.centres, t.centres_excluded]);
    Plotly.restyle(view, {name: "residuals " + label}, [t.residuals]);
    if (picked >= 0) { pick(picked, true); }  // the picked sample's chain ends where its centre is drawn now
  }

  function copyMatrix() {
    var text = document.getElementById("matrix").textContent, state = document.getElementById("copy-state");
    function done(ok) { state.textContent = ok ? " copied" : " select the text and copy it"; }
    function fallback() {
      var area = document.createElement("textarea");
      area.value = text;
      document.body.appendChild(area);
      area.select();
      var ok = false;
      try { ok = document.execCommand("copy"); } catch (err) { ok = false; }
      document.body.removeChild(area);
      done(ok);
    }
    if (navigator.clipboard && window.isSecureContext) {
      navigator.clipboard.writeText(text).then(function () { done(true); }, fallback);
    } else {
      fallback();
    }
  }

  function start() {
    if (table) {
      Array.prototype.forEach.call(table.tHead.rows[0].cells, function (th) {
        th.addEventListener("click", function () { sortBy(th); });
        th.addEventListener("keydown", function (ev) { if (ev.key === "Enter") { sortBy(th); } });
      });
      table.tBodies[0].addEventListener("click", function (ev) {
        var row = ev.target.closest("tr");
        if (row) { pick(parseInt(row.getAttribute("data-i"), 10)); }
      });
    }
    var button = document.getElementById("copy-matrix");
    if (button) { button.addEventListener("click", copyMatrix); }
    if (slider && cell) {
      slider.addEventListener("input", function () { rescale(Math.pow(10, parseFloat(slider.value))); });
    }
    if (plotted() && view.on) {
      view.on("plotly_click", function (ev) {
        var p = ev && ev.points && ev.points[0];
        if (p && p.customdata !== undefined && p.customdata !== null) { pick(Number(p.customdata)); }
      });
    }
    document.body.setAttribute("data-ready", plotted() ? "3d" : "static");
  }

  if (document.readyState === "complete") { start(); } else { window.addEventListener("load", start); }
}());

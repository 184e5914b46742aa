#include "output/report_page.hpp"

#include <algorithm>
#include <cstdint>

namespace ces::output {
namespace {

constexpr const char* kStyle = R"(
body { font: 14px/1.4 Helvetica, Arial, sans-serif; margin: 24px auto; max-width: 980px; color: #1a1a1a; }
h1 { font-size: 22px; margin-bottom: 4px; } h2 { font-size: 17px; margin-top: 28px; }
table { border-collapse: collapse; margin: 8px 0; } th, td { padding: 3px 10px; text-align: right; }
th { border-bottom: 1px solid #888; } td:first-child, th:first-child { text-align: left; }
.status { padding: 6px 10px; border-radius: 4px; display: inline-block; }
.complete { background: #e3f4e1; } .incomplete { background: #fbe3e1; }
.warnings li { color: #8a3b00; } img { max-width: 100%; border: 1px solid #ddd; }
canvas { border: 1px solid #ccc; background: #fff; } .controls { margin: 6px 0; }
.legend span { display: inline-block; margin-right: 14px; } .swatch { width: 10px; height: 10px; display: inline-block; margin-right: 4px; }
)";

// Everything the page shows is drawn from the data by this script; the
// body's data-rendered="ok" says it ran to the end (a test looks for it),
// data-error what stopped it.
constexpr const char* kScript = R"(
window.onerror = function (msg) { document.body.dataset.error = String(msg); };
const D = JSON.parse(document.getElementById('data').textContent);
const S = D.summary;
const el = (tag, attrs, text) => { const e = document.createElement(tag);
  Object.assign(e, attrs || {}); if (text !== undefined) e.textContent = text; return e; };
const fmt = (x, d) => (x === undefined || x === null || typeof x !== 'number') ? String(x) : x.toFixed(d);
const frac = x => fmt(x, 4);  // ratios as fractions, as in the files
const spread = (x, se) => frac(x) + ' ± ' + frac(se);  // a ratio and its standard error
const grams = kg => fmt(1000 * kg, 3);
function table(parent, head, rows) {
  const t = el('table'); const tr = el('tr');
  head.forEach(h => tr.appendChild(el('th', {}, h))); t.appendChild(tr);
  rows.forEach(r => { const row = el('tr'); r.forEach(c => row.appendChild(el('td', {}, c))); t.appendChild(row); });
  parent.appendChild(t);
}
function header() {
  const s = document.getElementById('status');
  s.className = 'status ' + (S.complete ? 'complete' : 'incomplete');
  s.textContent = (S.complete ? 'complete' : 'not complete: ' + S.reason) + ' · ' +
    fmt(S.simulated_time_s, 3) + ' s simulated in ' + fmt(S.wall_time_s.total, 1) + ' s · seed ' + S.seed;
  const w = document.getElementById('warnings');
  if (!S.warnings.length) w.appendChild(el('li', {}, 'none'));
  S.warnings.forEach(x => w.appendChild(el('li', {}, x)));
}
function products() {
  const p = document.getElementById('products');
  S.collectors.forEach(c => {
    p.appendChild(el('h3', {}, c.name + ': ' + c.collected.count + ' particles, ' + grams(c.collected.mass_kg) + ' g'));
    table(p, ['product', 'mass g', 'main material', 'grade ± s.e.', 'recovery ± s.e.'],
      c.products.map(x => [x.name, grams(x.mass_kg), x.main_material || '-', spread(x.grade, x.grade_se),
                           spread(x.recovery, x.recovery_se)]));
  });
}
function balance() {
  const b = S.balance, rows = [];
  for (const [name, m] of Object.entries(b.materials))
    rows.push([name, m.fed.count, grams(m.fed.mass_kg), m.collected.count, m.lost.count, m.active.count]);
  rows.push(['all', b.fed.count, grams(b.fed.mass_kg), b.collected.count, b.lost.count, b.active.count]);
  const p = document.getElementById('balance');
  table(p, ['material', 'fed', 'fed g', 'collected', 'lost', 'in the machine'], rows);
  p.appendChild(el('p', {}, 'mass balance ' + (b.exact ? 'exact' : 'NOT exact')));
}
function solver() {
  const s = S.solver, p = document.getElementById('solver');
  table(p, ['figure', 'value'], [
    ['method', s.method], ['iterations (mean / max)', fmt(s.iterations_mean, 1) + ' / ' + s.iterations_max],
    ['steps at the iteration cap', s.steps_at_iteration_cap + ' of ' + s.steps_solved],
    ['residual p95 (m/s)', s.residual_p95_mps.toExponential(2)],
    ['worst overlap / radius', frac(s.max_penetration_relative)],
    ['worst wall penetration / radius', frac(s.max_wall_penetration_relative)],
    ['deepest give of a yielding surface (mm)', fmt(1e3 * s.max_surface_yield_m, 3)]]);
  table(p, ['stage', 'wall s'], Object.entries(S.wall_time_s.stages).map(([k, v]) => [k, fmt(v, 3)]));
}
const palette = ['#c0392b', '#2471a3', '#229954', '#d68910', '#7d3c98', '#17a589', '#566573', '#a04000'];
function animation() {
  const canvas = document.getElementById('section'), ctx = canvas.getContext('2d');
  const M = D.machine, F = D.frames;
  let x0 = Infinity, x1 = -Infinity, y0 = Infinity, y1 = -Infinity;
  const grow = (x, y) => { x0 = Math.min(x0, x); x1 = Math.max(x1, x); y0 = Math.min(y0, y); y1 = Math.max(y1, y); };
  M.circles.forEach(c => { grow(c.x - c.r, c.y - c.r); grow(c.x + c.r, c.y + c.r); });
  M.polygons.forEach(p => { for (let i = 0; i < p.points.length; i += 2) grow(p.points[i], p.points[i + 1]); });
  M.collectors.forEach(c => { grow(c.points[0], c.points[1]); grow(c.points[2], c.points[3]); });
  if (!isFinite(x0)) { x0 = -1000; x1 = 1000; y0 = -1000; y1 = 1000; }
  const pad = 0.05 * Math.max(x1 - x0, y1 - y0);
  x0 -= pad; x1 += pad; y0 -= pad; y1 += pad;
  const scale = Math.min(canvas.width / (x1 - x0), canvas.height / (y1 - y0));
  const X = x => (x - x0) * scale, Y = y => canvas.height - (y - y0) * scale;
  let qmax = 0;
  F.forEach(f => f.q.forEach(q => { qmax = Math.max(qmax, Math.abs(q)); }));
  const mode = document.getElementById('colour'), slider = document.getElementById('frame');
  const label = document.getElementById('time');
  slider.max = Math.max(0, F.length - 1);
  function chargeColour(q) {
    const a = qmax > 0 ? Math.min(1, Math.abs(q) / qmax) : 0, v = Math.round(200 * (1 - a));
    return q < 0 ? `rgb(${v},${v},255)` : `rgb(255,${v},${v})`;
  }
  function draw(k) {
    ctx.clearRect(0, 0, canvas.width, canvas.height);
    ctx.strokeStyle = '#555'; ctx.lineWidth = 1.5;
    M.circles.forEach(c => { ctx.beginPath(); ctx.arc(X(c.x), Y(c.y), c.r * scale, 0, 2 * Math.PI); ctx.stroke(); });
    M.polygons.forEach(p => { ctx.beginPath(); ctx.moveTo(X(p.points[0]), Y(p.points[1]));
      for (let i = 2; i < p.points.length; i += 2) ctx.lineTo(X(p.points[i]), Y(p.points[i + 1]));
      ctx.closePath(); ctx.stroke(); });
    ctx.setLineDash([4, 4]);
    M.collectors.forEach(c => { ctx.beginPath(); ctx.moveTo(X(c.points[0]), Y(c.points[1]));
      ctx.lineTo(X(c.points[2]), Y(c.points[3])); ctx.stroke(); });
    ctx.setLineDash([]);
    const f = F[k];
    if (!f) { label.textContent = 'no frames'; return; }
    const byCharge = mode.value === 'charge';
    for (let i = 0; i < f.x.length; ++i) {
      ctx.fillStyle = byCharge ? chargeColour(f.q[i]) : palette[f.m[i] % palette.length];
      ctx.fillRect(X(f.x[i]) - 1.5, Y(f.y[i]) - 1.5, 3, 3);
    }
    label.textContent = 't = ' + fmt(f.t, 3) + ' s, ' + f.x.length + ' particles drawn';
  }
  function legend() {
    const l = document.getElementById('legend'); l.textContent = '';
    if (mode.value === 'charge') {
      l.appendChild(el('span', {}, 'blue: negative, red: positive, up to ' + qmax.toExponential(2) + ' C'));
      return;
    }
    D.materials.forEach((name, m) => { if (!(name in S.balance.materials)) return; const s = el('span');
      const sw = el('span', {className: 'swatch'}); sw.style.background = palette[m % palette.length];
      s.appendChild(sw); s.appendChild(document.createTextNode(name)); l.appendChild(s); });
  }
  let timer = null;
  document.getElementById('play').onclick = function () {
    if (timer) { clearInterval(timer); timer = null; this.textContent = 'play'; return; }
    this.textContent = 'pause';
    timer = setInterval(() => { slider.value = (Number(slider.value) + 1) % F.length; draw(Number(slider.value)); }, 100);
  };
  slider.oninput = () => draw(Number(slider.value));
  mode.onchange = () => { legend(); draw(Number(slider.value)); };
  slider.value = slider.max; legend(); draw(Number(slider.value));
}
header(); products(); balance(); solver(); animation();
document.body.dataset.rendered = 'ok';
)";

std::string escaped(const std::string& text) {
  std::string out;
  for (const char c : text) {
    if (c == '<') out += "&lt;";
    else if (c == '>') out += "&gt;";
    else if (c == '&') out += "&amp;";
    else if (c == '"') out += "&quot;";
    else out += c;
  }
  return out;
}

std::string picture(const std::string& heading, const std::string& svg) {
  if (svg.empty()) return "";
  return "<h2>" + heading + "</h2>\n<img alt=\"" + heading + "\" src=\"data:image/svg+xml;base64," +
         base64(svg) + "\">\n";
}

}  // namespace

std::string base64(const std::string& bytes) {
  static constexpr char kDigits[] =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  for (std::size_t i = 0; i < bytes.size(); i += 3) {
    const std::size_t n = std::min<std::size_t>(3, bytes.size() - i);
    std::uint32_t v = 0;
    for (std::size_t j = 0; j < 3; ++j)
      v = (v << 8) | (j < n ? static_cast<unsigned char>(bytes[i + j]) : 0u);
    for (std::size_t j = 0; j < 4; ++j)
      out += j <= n ? kDigits[(v >> (18 - 6 * j)) & 63] : '=';
  }
  return out;
}

std::string report_page(const std::string& title, const std::string& data,
                        const std::string& distribution_svg, const std::string& field_svg) {
  const std::string name = escaped(title);
  return "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
         "<title>" + name + ": ces-sim report</title>\n<style>" + kStyle +
         "</style>\n</head>\n<body>\n<h1>" + name + "</h1>\n<div id=\"status\"></div>\n"
         "<h2>Warnings</h2>\n<ul id=\"warnings\" class=\"warnings\"></ul>\n"
         "<h2>Products</h2>\n<div id=\"products\"></div>\n"
         "<h2>Balance</h2>\n<div id=\"balance\"></div>\n" +
         picture("Landing distribution", distribution_svg) +
         "<h2>Cross section</h2>\n<div class=\"controls\"><button id=\"play\">play</button> "
         "<input id=\"frame\" type=\"range\" min=\"0\" value=\"0\"> colour by "
         "<select id=\"colour\"><option value=\"material\">material</option>"
         "<option value=\"charge\">charge</option></select> <span id=\"time\"></span></div>\n"
         "<canvas id=\"section\" width=\"900\" height=\"560\"></canvas>\n"
         "<div id=\"legend\" class=\"legend\"></div>\n" +
         picture("Electric field", field_svg) +
         "<h2>Solver</h2>\n<div id=\"solver\"></div>\n"
         "<script type=\"application/json\" id=\"data\">" + data + "</script>\n<script>" +
         kScript + "</script>\n</body>\n</html>\n";
}

}  // namespace ces::output

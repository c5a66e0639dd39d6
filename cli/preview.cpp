// SPDX-License-Identifier: GPL-3.0-or-later
// The preview page. What it may call: see preview.hpp.
#include "cli/preview.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace xlate5::cli {

namespace {

constexpr int kDeviationSamples = 8;  // interior points per written move

double segment_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    const Eigen::Vector3d ab = b - a;
    const double len2 = ab.squaredNorm();
    const double t = len2 > 0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
    return (a + t * ab - p).norm();
}

std::string num(double v) {
    if (!std::isfinite(v)) return "null";
    char b[32];
    std::snprintf(b, sizeof b, "%.4g", v);
    return b;
}

std::string html_text(const std::string& s) {
    std::string o;
    for (char c : s) {
        if (c == '<') o += "&lt;";
        else if (c == '>') o += "&gt;";
        else if (c == '&') o += "&amp;";
        else o += c;
    }
    return o;
}

// The page's script: plain JavaScript on a 2D canvas, no library, no network.
const char* kScript = R"JS(
const D = JSON.parse(document.getElementById('data').textContent);
const KIND = {pole: {colour: 'magenta', text: 'pole crossing'}, unwind: {colour: 'darkorange', text: 'unwind (whole turns)'},
              branch: {colour: 'green', text: 'branch change (the other solution)'}, rezero: {colour: 'grey', text: 're-zero (G92)'}};
const n = D.q.length, J = D.joints.length;
const tips = [], axes = [];
for (const p of D.pose) { tips.push([p[0], p[1], p[2]]); axes.push([p[3], p[4], p[5]]); }
// Framed on the printed moves when there are any (a travel from home would shrink the part).
const framed = D.pose.some(p => p[7]) ? tips.filter((t, i) => D.pose[i][7]) : tips;
let lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
for (const t of framed) for (let k = 0; k < 3; k++) { lo[k] = Math.min(lo[k], t[k]); hi[k] = Math.max(hi[k], t[k]); }
const centre = lo.map((v, k) => (v + hi[k]) / 2);
const size = Math.max(1e-6, ...hi.map((v, k) => v - lo[k]));
let yaw = -0.6, pitch = 0.9;
const view = document.getElementById('view'), g = view.getContext('2d');
const mode = document.getElementById('colour');
if (location.hash === '#deviation') mode.value = 'dev';  // a link straight to the deviation view
function colour(p) {  // tilt: 0 degrees blue, the file's largest red; deviation: 0 blue, the tolerance red
  const f = mode.value === 'dev' ? Math.min(1, p[8] / D.tolerance) : (D.max_tilt > 0 ? Math.min(1, p[6] / D.max_tilt) : 0);
  return 'hsl(' + Math.round(240 * (1 - f)) + ',85%,45%)';
}
function project(p) {
  const x = p[0] - centre[0], y = p[1] - centre[1], z = p[2] - centre[2];
  const x1 = x * Math.cos(yaw) - y * Math.sin(yaw), y1 = x * Math.sin(yaw) + y * Math.cos(yaw);
  const y2 = y1 * Math.cos(pitch) - z * Math.sin(pitch);
  const s = 0.8 * Math.min(view.width, view.height) / size;
  return [view.width / 2 + x1 * s, view.height / 2 + y2 * s];
}
function draw() {
  g.fillStyle = '#fff'; g.fillRect(0, 0, view.width, view.height);
  const whisker = 0.06 * size, step = Math.max(1, Math.floor(n / 150));
  g.lineWidth = 1;
  for (let i = 0; i < n; i += step) {
    if (!D.pose[i][7] && framed !== tips) continue;
    const a = project(tips[i]), b = project(tips[i].map((v, k) => v + whisker * axes[i][k]));
    g.strokeStyle = 'rgba(0,0,0,0.25)'; g.beginPath(); g.moveTo(a[0], a[1]); g.lineTo(b[0], b[1]); g.stroke();
  }
  g.lineWidth = 1.5;
  for (let i = 1; i < n; i++) {
    const a = project(tips[i - 1]), b = project(tips[i]);
    g.strokeStyle = D.pose[i][7] || framed === tips ? colour(D.pose[i]) : 'rgba(0,0,0,0.15)'; g.beginPath(); g.moveTo(a[0], a[1]); g.lineTo(b[0], b[1]); g.stroke();
  }
  for (const m of D.marks) {  // pole crossings: rings; unwinds, branch changes, re-zeros: squares
    const a = project([m[2], m[3], m[4]]);
    g.lineWidth = 2; g.strokeStyle = KIND[m[0]].colour; g.beginPath();
    if (m[0] === 'pole') g.arc(a[0], a[1], 6, 0, 2 * Math.PI); else g.rect(a[0] - 5, a[1] - 5, 10, 10);
    g.stroke();
  }
  g.fillStyle = '#000'; g.font = '12px sans-serif';
  g.fillText((mode.value === 'dev' ? 'deviation: blue 0 \u2026 red ' + D.tolerance + ' mm (the tolerance) and beyond'
                                   : 'tilt: blue 0\u00b0 \u2026 red ' + D.max_tilt.toFixed(1) + '\u00b0') +
             '; grey: tool axis; faint: travel.', 8, 16);
  g.fillText('Magenta ring: pole crossing; squares: orange unwind, green branch change, grey re-zero. Drag to turn.', 8, 32);
}
mode.addEventListener('change', draw);
let drag = null;
view.addEventListener('mousedown', e => { drag = [e.clientX, e.clientY]; });
window.addEventListener('mouseup', () => { drag = null; });
window.addEventListener('mousemove', e => {
  if (!drag) return;
  yaw += (e.clientX - drag[0]) * 0.01; pitch += (e.clientY - drag[1]) * 0.01; drag = [e.clientX, e.clientY]; draw();
});
draw();
const panel = document.getElementById('joints');
D.joints.forEach((j, k) => {
  const c = document.createElement('canvas'); c.width = 900; c.height = 90; panel.appendChild(c);
  const h = c.getContext('2d');
  const vals = D.q.map(r => r[k]);
  let a = Math.min(...vals), b = Math.max(...vals);
  if (j.min !== null) a = Math.min(a, j.min);
  if (j.max !== null) b = Math.max(b, j.max);
  if (!(b > a)) { a -= 1; b += 1; }
  const Y = v => 80 - (v - a) / (b - a) * 70, X = i => 60 + i / Math.max(1, n - 1) * 830;
  h.fillStyle = '#fff'; h.fillRect(0, 0, c.width, c.height);
  h.strokeStyle = 'red'; h.setLineDash([5, 4]);
  for (const lim of [j.min, j.max]) if (lim !== null) { h.beginPath(); h.moveTo(60, Y(lim)); h.lineTo(890, Y(lim)); h.stroke(); }
  h.setLineDash([]); h.strokeStyle = 'steelblue'; h.beginPath();
  vals.forEach((v, i) => { if (i) h.lineTo(X(i), Y(v)); else h.moveTo(X(i), Y(v)); }); h.stroke();
  h.fillStyle = '#000'; h.font = '12px sans-serif';
  h.fillText(j.name + ' ' + j.unit, 4, 14);
  h.fillText(j.low.toFixed(2) + ' \u2026 ' + j.high.toFixed(2), 4, 86);
  for (const m of D.marks) {
    const x = 60 + m[1] * 830;
    h.strokeStyle = KIND[m[0]].colour; h.beginPath(); h.moveTo(x, 10); h.lineTo(x, 80); h.stroke();
  }
});
const list = document.getElementById('marks');
D.marks.slice(0, 100).forEach(m => {
  const li = document.createElement('li'); li.dataset.kind = m[0];
  li.textContent = KIND[m[0]].text + ' at written move ' + m[5] +
                   ' (tip ' + m.slice(2, 5).map(v => v.toFixed(2)).join(', ') + ')';
  list.appendChild(li);
});
if (D.marks.length > 100) { const li = document.createElement('li'); li.textContent = 'and ' + (D.marks.length - 100) + ' more'; list.appendChild(li); }
document.title = document.title + ' (drawn)';
)JS";

const char* kind_name(DeviationReport::MarkKind kind) {
    switch (kind) {
        case DeviationReport::MarkKind::PoleCrossing: return "pole";
        case DeviationReport::MarkKind::Unwind: return "unwind";
        case DeviationReport::MarkKind::BranchChange: return "branch";
        case DeviationReport::MarkKind::Rezero: return "rezero";
    }
    return "";
}

}  // namespace

Preview::Preview(const Kinematics& kinematics, const DeviationReport& events)
    : kin_(kinematics), events_(events), joints_(kinematics.machine().joints.size()), q_now_(kinematics.machine().home_joints()),
      low_(q_now_), high_(q_now_), q_before_(q_now_) {}

void Preview::scan(std::string_view output) {
    while (!output.empty()) {
        const auto nl = output.find('\n');
        if (nl == std::string_view::npos) {
            pending_.append(output);  // rare: a block never ends mid-line today
            return;
        }
        if (!pending_.empty()) {
            pending_.append(output.substr(0, nl));
            line(pending_);
            pending_.clear();
        } else {
            line(output.substr(0, nl));
        }
        output.remove_prefix(nl + 1);
    }
}

void Preview::line(std::string_view l) {
    if (l.size() < 3 || l[0] != 'G') return;
    const auto& home_of = kin_.machine().joints;
    if (l.substr(0, 3) == "G28" && (l.size() == 3 || l[3] == ' ' || l[3] == ';')) {  // homing: the named joints, or all
        bool named = false;
        for (std::size_t j = 0; j < joints_; ++j)
            if (l.find(home_of[j].output, 3) != std::string_view::npos) q_now_[j] = home_of[j].home, named = true;
        if (!named) q_now_ = kin_.machine().home_joints();
        return;
    }
    const bool move = (l[1] == '0' || l[1] == '1') && l[2] == ' ';
    const bool set = l.size() > 3 && l.substr(0, 4) == "G92 ";
    if (!move && !set) return;
    const auto& joints = kin_.machine().joints;
    printing_ = false;
    q_before_ = q_now_;
    // Words "L<number>" separated by blanks, up to a comment.
    for (std::size_t i = 3; i < l.size();) {
        if (l[i] == ';' || l[i] == '(') break;
        if (l[i] == ' ') {
            ++i;
            continue;
        }
        const char letter = l[i];
        std::size_t end = l.find(' ', i);
        if (end == std::string_view::npos) end = l.size();
        const std::string word(l.substr(i + 1, end - i - 1));
        i = end;
        char* stop = nullptr;
        const double v = std::strtod(word.c_str(), &stop);
        if (stop == word.c_str() || !std::isfinite(v)) continue;
        if (letter == 'E' && move) printing_ = true;
        for (std::size_t j = 0; j < joints_; ++j)
            if (joints[j].output == letter) q_now_[j] = v;
    }
    if (!move) return;
    bool turned = false;
    for (std::size_t j = 0; j < joints_; ++j) turned = turned || (joints[j].rotary && q_now_[j] != q_before_[j]);
    for (std::size_t j = 0; j < joints_; ++j) low_[j] = std::min(low_[j], q_now_[j]), high_[j] = std::max(high_[j], q_now_[j]);
    if (turned) dev_since_ = std::max(dev_since_, deviation(q_before_, q_now_));
    ++moves_;
    join_marks(moves_);  // the events of the moves that ended on this line
    if ((moves_ - 1) % every_ == 0) keep();
}

// The report's events up to the move line numbered `through` (from 1), placed on the written
// move they ended on: the joints and tip there are what the firmware is told.
void Preview::join_marks(std::uint64_t through) {
    const auto& marks = events_.marks();
    for (; joined_ < marks.size() && marks[joined_].moves_written <= through; ++joined_) {
        const Eigen::Vector3d tip = kin_.forward(q_now_).tip;
        const std::uint64_t move = marks[joined_].moves_written > 0 ? marks[joined_].moves_written - 1 : 0;
        marks_.push_back({marks[joined_].kind, move, {tip.x(), tip.y(), tip.z()}});
    }
}

double Preview::deviation(const std::vector<double>& from, const std::vector<double>& to) const {
    std::vector<double> q(from.size());
    const Eigen::Vector3d a = kin_.forward(from).tip, b = kin_.forward(to).tip;
    double worst = 0;
    for (int i = 1; i <= kDeviationSamples; ++i) {
        const double t = double(i) / (kDeviationSamples + 1);
        for (std::size_t j = 0; j < q.size(); ++j) q[j] = from[j] + t * (to[j] - from[j]);
        worst = std::max(worst, segment_distance(kin_.forward(q).tip, a, b));
    }
    return worst;
}

void Preview::keep() {
    q_.insert(q_.end(), q_now_.begin(), q_now_.end());
    prints_.push_back(printing_ ? 1 : 0);
    dev_.push_back(dev_since_);
    dev_since_ = 0;
    if (q_.size() / joints_ < kMaxPoints) return;
    // Full: keep every other kept move, and keep every 2 * every_ -th from now on.
    std::size_t w = 0;
    for (std::size_t r = 0; r < q_.size() / joints_; r += 2, ++w) {
        std::copy_n(q_.begin() + std::ptrdiff_t(r * joints_), joints_, q_.begin() + std::ptrdiff_t(w * joints_));
        prints_[w] = prints_[r];
        dev_[w] = std::max(dev_[r], r > 0 ? dev_[r - 1] : 0.0);  // the dropped move before it
    }
    const std::size_t kept = q_.size() / joints_;
    if (kept % 2 == 0) dev_since_ = std::max(dev_since_, dev_[kept - 1]);  // the dropped last one: with the next
    q_.resize(w * joints_);
    prints_.resize(w);
    dev_.resize(w);
    every_ *= 2;
}

std::string Preview::html(const std::string& title) const {
    const auto& m = kin_.machine();
    const std::size_t n = q_.size() / joints_;
    std::string data = "{\"q\": [";
    std::string pose = "\"pose\": [";
    double max_tilt = 0;
    std::vector<double> q(joints_);
    for (std::size_t i = 0; i < n; ++i) {
        std::copy_n(q_.begin() + std::ptrdiff_t(i * joints_), joints_, q.begin());
        data += i ? ",[" : "[";
        for (std::size_t j = 0; j < joints_; ++j) {
            if (j) data += ',';
            data += num(q[j]);
        }
        data += "]";
        const Pose p = kin_.forward(q);
        const double tilt = std::acos(std::clamp(p.axis.z(), -1.0, 1.0)) * 180.0 / M_PI;
        max_tilt = std::max(max_tilt, tilt);
        pose += std::string(i ? "," : "") + "[" + num(p.tip.x()) + "," + num(p.tip.y()) + "," + num(p.tip.z()) + "," + num(p.axis.x()) + "," +
                num(p.axis.y()) + "," + num(p.axis.z()) + "," + num(tilt) + "," + (prints_[i] ? "1" : "0") + "," + num(dev_[i]) + "]";
    }
    data += "], " + pose + "], \"max_tilt\": " + num(max_tilt) + ", \"tolerance\": " + num(m.motion.tolerance) + ", \"marks\": [";
    // Every mark the report kept (one not yet joined, for a move after the last line read, sits on the last move).
    const auto& events = events_.marks();
    std::vector<Mark> marks = marks_;
    for (std::size_t i = joined_; i < events.size(); ++i) {
        const Eigen::Vector3d tip = kin_.forward(q_now_).tip;
        marks.push_back({events[i].kind, moves_ > 0 ? moves_ - 1 : 0, {tip.x(), tip.y(), tip.z()}});
    }
    for (std::size_t i = 0; i < marks.size(); ++i) {
        const Mark& k = marks[i];
        // Along the joint charts, which draw the kept moves (every every_-th written move from the
        // first) evenly: a mark sits where its move is, between the kept ones around it.
        const double at = n > 1 ? std::min(1.0, double(k.move) / double(every_) / double(n - 1)) : 0.0;
        data += std::string(i ? "," : "") + "[\"" + kind_name(k.kind) + "\"," + num(at) + "," + num(k.tip[0]) + "," + num(k.tip[1]) + "," +
                num(k.tip[2]) + "," + std::to_string(k.move) + "]";
    }
    data += "], \"joints\": [";
    for (std::size_t j = 0; j < joints_; ++j) {
        const auto& J = m.joints[j];
        data += std::string(j ? "," : "") + "{\"name\": \"" + J.output + "\", \"unit\": \"" + (J.rotary ? "deg" : "mm") +
                "\", \"min\": " + (J.min > -1e299 ? num(J.min) : "null") + ", \"max\": " + (J.max < 1e299 ? num(J.max) : "null") +
                ", \"low\": " + num(low_[j]) + ", \"high\": " + num(high_[j]) + "}";
    }
    data += "]}";
    const std::uint64_t total = events_.pole_crossings() + events_.unwinds() + events_.branch_changes() + events_.rezeros();
    std::string o = "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>xlate5 preview: " + html_text(title) +
                    "</title>\n<style>body{font-family:sans-serif;margin:12px}canvas{display:block;border:1px solid #ccc;margin:4px 0}</style>"
                    "</head>\n<body>\n<h3>" + html_text(title) + "</h3>\n<p>" + std::to_string(moves_) + " moves written, " +
                    std::to_string(n) + " shown. " + std::to_string(events_.pole_crossings()) + " pole crossings, " +
                    std::to_string(events_.unwinds()) + " unwinds, " + std::to_string(events_.branch_changes()) + " branch changes, " +
                    std::to_string(events_.rezeros()) + " re-zeros marked" +
                    (total > marks.size() ? " (the first " + std::to_string(marks.size()) + " of " + std::to_string(total) + ")" : "") +
                    ". Joints over the file below, their limits dashed red.</p>\n"
                    "<p>Colour by <select id=\"colour\"><option value=\"tilt\">tilt</option><option value=\"dev\">deviation</option></select></p>\n"
                    "<canvas id=\"view\" width=\"900\" height=\"600\"></canvas>\n<div id=\"joints\"></div>\n<ul id=\"marks\"></ul>\n"
                    "<script type=\"application/json\" id=\"data\">" + data + "</script>\n<script>" + kScript + "</script>\n</body></html>\n";
    return o;
}

}  // namespace xlate5::cli

// SPDX-License-Identifier: GPL-3.0-or-later
// The preview's collection: the written output read back. What it may call: see preview.hpp.
#include "translators/inspect/preview.hpp"

#include "translators/pipeline/motion.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>

namespace xlate5 {

namespace {

constexpr int kDeviationSamples = 8;  // interior points per written move

double segment_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    const Eigen::Vector3d ab = b - a;
    const double len2 = ab.squaredNorm();
    const double t = len2 > 0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
    return (a + t * ab - p).norm();
}

}  // namespace

PreviewMark::Kind PreviewMark::of(DeviationReport::MarkKind k) {
    switch (k) {
        case DeviationReport::MarkKind::PoleCrossing: return Kind::PoleCrossing;
        case DeviationReport::MarkKind::Unwind: return Kind::Unwind;
        case DeviationReport::MarkKind::BranchChange: return Kind::BranchChange;
        case DeviationReport::MarkKind::Rezero: return Kind::Rezero;
    }
    return Kind::Rezero;
}

Preview::Preview(const Kinematics& kinematics, const DeviationReport& events)
    : kin_(kinematics), events_(events), joints_(kinematics.machine().joints.size()), q_now_(kinematics.machine().home_joints()),
      q_before_(q_now_) {
    data_.kept.joints = joints_;
    data_.low = data_.high = q_now_;
}

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
    ++lines_;
    current_ = l;
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
        if (letter == 'F' && move) f_ = v;
        for (std::size_t j = 0; j < joints_; ++j)
            if (joints[j].output == letter) q_now_[j] = v;
    }
    if (!move) return;
    bool turned = false;
    for (std::size_t j = 0; j < joints_; ++j) turned = turned || (joints[j].rotary && q_now_[j] != q_before_[j]);
    for (std::size_t j = 0; j < joints_; ++j) data_.low[j] = std::min(data_.low[j], q_now_[j]), data_.high[j] = std::max(data_.high[j], q_now_[j]);
    if (turned) {
        const double d = deviation(q_before_, q_now_, true);
        dev_since_ = std::max(dev_since_, d);
        // The worst swing since the last kept move is drawn with it.
        if (d > kin_.machine().motion.tolerance && d > swing_dev_) swing_dev_ = d, swing_since_ = swing_now_;
    }
    check_feed();
    ++data_.moves;
    join_marks(data_.moves);  // the events of the moves that ended on this line
    if ((data_.moves - 1) % data_.kept.every == 0) keep();
}

// A move that runs a joint at its max_feed at the written feed: the translation slowed it to
// that (or the program asked for exactly that much). The feed's length is the dialect's
// (firmware_length); inverse-time feeds (G93) are not checked.
void Preview::check_feed() {
    const Machine& m = kin_.machine();
    bool slowed = false;
    if (!m.dialect.inverse_time && f_ > 0) {
        const double length = firmware_length(m, q_before_, q_now_);
        if (length > 0)
            for (std::size_t j = 0; j < joints_ && !slowed; ++j)
                if (m.joints[j].max_feed > 0 && std::abs(q_now_[j] - q_before_[j]) * f_ / length >= kAtMaxFeed * m.joints[j].max_feed) slowed = true;
    }
    if (slowed) {
        ++data_.slowed;
        if (!slowed_last_) {  // a run of such moves is one mark, at its first move
            ++data_.slowed_runs;
            if (data_.slowed_marks.size() < kMaxReportMarks) {
                const Eigen::Vector3d tip = kin_.forward(q_now_).tip;
                data_.slowed_marks.push_back({Kind::Slowed, data_.moves, {tip.x(), tip.y(), tip.z()}});
            }
        }
    }
    slowed_last_ = slowed;
}

// The report's events up to the move line numbered `through` (from 1), placed on the written
// move they ended on: the joints and tip there are what the firmware is told.
void Preview::join_marks(std::uint64_t through) {
    const auto& marks = events_.marks();
    for (; joined_ < marks.size() && marks[joined_].moves_written <= through; ++joined_) {
        const Eigen::Vector3d tip = kin_.forward(q_now_).tip;
        const std::uint64_t move = marks[joined_].moves_written > 0 ? marks[joined_].moves_written - 1 : 0;
        data_.marks.push_back({PreviewMark::of(marks[joined_].kind), move, {tip.x(), tip.y(), tip.z()}});
    }
}

double Preview::deviation(const std::vector<double>& from, const std::vector<double>& to, bool keep_samples) {
    std::vector<double> q(from.size());
    const Eigen::Vector3d a = kin_.forward(from).tip, b = kin_.forward(to).tip;
    double worst = 0;
    if (keep_samples) swing_now_.clear();
    for (int i = 1; i <= kDeviationSamples; ++i) {
        const double t = double(i) / (kDeviationSamples + 1);
        for (std::size_t j = 0; j < q.size(); ++j) q[j] = from[j] + t * (to[j] - from[j]);
        const Eigen::Vector3d p = kin_.forward(q).tip;
        if (keep_samples) swing_now_.insert(swing_now_.end(), {p.x(), p.y(), p.z()});
        worst = std::max(worst, segment_distance(p, a, b));
    }
    return worst;
}

void Preview::keep() {
    KeptMoves& k = data_.kept;
    k.q.insert(k.q.end(), q_now_.begin(), q_now_.end());
    k.prints.push_back(printing_ ? 1 : 0);
    k.dev.push_back(dev_since_);
    k.feed.push_back(f_);
    k.move_no.push_back(data_.moves - 1);
    k.line_no.push_back(lines_);
    k.text.emplace_back(current_.substr(0, KeptMoves::kLineText));
    k.swing.push_back(swing_dev_ > 0 && k.every == 1 ? swing_since_ : std::vector<double>());
    dev_since_ = 0, swing_dev_ = 0;
    if (k.size() >= KeptMoves::kMaxPoints) k.halve(dev_since_);
}

void KeptMoves::halve(double& dev_since) {
    // Keep every other kept move, and keep every 2 * every -th from now on.
    std::size_t w = 0;
    for (std::size_t r = 0; r < q.size() / joints; r += 2, ++w) {
        std::copy_n(q.begin() + std::ptrdiff_t(r * joints), joints, q.begin() + std::ptrdiff_t(w * joints));
        prints[w] = prints[r];
        dev[w] = std::max(dev[r], r > 0 ? dev[r - 1] : 0.0);  // the dropped move before it
        feed[w] = feed[r], move_no[w] = move_no[r], line_no[w] = line_no[r];
        text[w] = std::move(text[r]);
        swing[w].clear();  // its chord is now from a farther kept move: drawn straight
    }
    const std::size_t kept = q.size() / joints;
    if (kept % 2 == 0) dev_since = std::max(dev_since, dev[kept - 1]);  // the dropped last one: with the next
    q.resize(w * joints);
    prints.resize(w), dev.resize(w), feed.resize(w), move_no.resize(w), line_no.resize(w), text.resize(w), swing.resize(w);
    every *= 2;
}

std::string Preview::report_json() const {
    return "  \"move_lines_written\": " + std::to_string(data_.moves) + ",\n  \"moves_at_joint_max_feed\": " + std::to_string(data_.slowed) +
           ",\n  \"runs_at_joint_max_feed\": " + std::to_string(data_.slowed_runs) + ",\n";
}

std::string Preview::html(const std::string& title) const {
    // Every mark the report kept (one not yet joined, for a move after the last line read, sits on the last move).
    const auto& events = events_.marks();
    std::vector<Mark> marks = data_.marks;
    for (std::size_t i = joined_; i < events.size(); ++i) {
        const Eigen::Vector3d tip = kin_.forward(q_now_).tip;
        marks.push_back({PreviewMark::of(events[i].kind), data_.moves > 0 ? data_.moves - 1 : 0, {tip.x(), tip.y(), tip.z()}});
    }
    return preview_page(kin_, events_, data_, marks, title);
}

}  // namespace xlate5

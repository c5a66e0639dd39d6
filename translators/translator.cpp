#include "translators/translator.hpp"

#include <algorithm>
#include <cmath>

#include "translators/error.hpp"
#include "translators/number.hpp"

namespace xlate5 {

namespace {

// G codes that only set a mode and take no words; they run before the line's command.
bool is_modal_only(int code10) {
    switch (code10) {
        case 170: case 180: case 190:              // plane
        case 200: case 210:                        // units
        case 400: case 410: case 420:              // cutter compensation
        case 434: case 435: case 490:              // tool-centre-point control
        case 540: case 550: case 560: case 570: case 580: case 590: case 591: case 592: case 593:
        case 610: case 611: case 640:              // path control
        case 800:                                  // canned cycle cancel
        case 900: case 910: case 901: case 911:    // distance modes
        case 930: case 940:                        // feed modes
            return true;
        default:
            return false;
    }
}

// RS274's order of execution within a line for the mode-only codes (feed mode, plane, units,
// cutter compensation, tool length / TCP, coordinate system, path control, distance mode), so a
// line means the same whatever order its words are written in.
int modal_rank(int code10) {
    switch (code10) {
        case 930: case 940: return 0;
        case 170: case 180: case 190: return 1;
        case 200: case 210: return 2;
        case 400: case 410: case 420: return 3;
        case 434: case 435: case 490: return 4;
        case 610: case 611: case 640: return 6;
        case 900: case 910: case 901: case 911: return 7;
        case 800: return 8;
        default: return 5;  // G54..G59.3
    }
}

// M-codes whose T word names a tool (M104 T1 S200), rather than T being a tool change.
bool m_takes_tool(int code10) {
    switch (code10) {
        case 1040: case 1050: case 1060: case 1070: case 1090: case 2000: case 2180: case 2210:
        case 3010: case 3030: case 3060: case 6000: case 7010: case 7020: case 9060: case 9130: case 9140:
            return true;
        default:
            return false;
    }
}

void append_code(std::string& out, char letter, int code10) {
    out += letter;
    append_fixed(out, code10 / 10.0, 1);
}

bool blank(std::string_view s) {
    for (char c : s)
        if (c != ' ' && c != '\t' && c != '\r') return false;
    return true;
}

}  // namespace

Translator::Translator(const Kinematics& kinematics, TranslatorOptions options)
    : kin_(kinematics),
      machine_(kinematics.machine()),
      options_(std::move(options)),
      emitter_(kinematics.machine()),
      tool_emitter_(kinematics.machine(), options_.preview_form),
      motion_(kinematics, emitter_),
      q_(machine_.home_joints()),
      q_next_(q_),
      sent_q_(q_),
      commanded_(q_.size(), false),
      pose_(kin_.forward(q_)),
      mode_(options_.inverse ? OrientationMode::Joints : options_.start_mode.value_or(machine_.start_mode)),
      before_line_(kinematics.machine()),
      checkpoint_(kinematics.machine()) {}

int Translator::joint_of(char letter) const {
    if (!options_.inverse) return machine_.joint_index(letter);
    for (std::size_t j = 0; j < machine_.joints.size(); ++j)
        if (machine_.joints[j].output == letter) return int(j);
    return -1;
}

void Translator::fail(std::uint32_t column, const std::string& message) const {
    throw InputError(options_.input_name, line_no_, column, message);
}

const Translator::Param* Translator::find(char letter) const {
    for (const auto& p : params_)
        if (p.letter == letter) return &p;
    return nullptr;
}

double Translator::number(const Param& p) const {
    if (!p.has_value) fail(p.column, std::string("word ") + p.letter + " has no number");
    return p.value;
}

PassedNumber Translator::passed(const Param& p) const {
    const double v = number(p);
    if (modes_.inches) return {v * 25.4, {}};
    return {v, p.text};
}

bool Translator::is_axis_letter(char c) const {
    return c == 'X' || c == 'Y' || c == 'Z' || c == 'I' || c == 'J' || c == 'K' || joint_of(c) >= 0;
}

void Translator::feed_line(std::string_view line, std::uint64_t line_no, std::string& out) {
    line_no_ = line_no;
    line_travels_ = false;
    line_hit_limit_ = false;
    try {
        lex_line(line, block_);
    } catch (const LineError& e) {
        throw InputError(options_.input_name, line_no, e.column(), e.what());
    }
    if (block_.words.empty()) {
        if (!block_.body.empty()) {
            out += block_.body;
            out += '\n';
        } else if (blank(line)) {
            out += '\n';
        }
        return;
    }

    struct Command {
        char letter;
        int code10;
        std::uint32_t column;
    };
    Command commands[16];
    std::size_t n_commands = 0;
    params_.clear();
    bool tool_word_is_param = false;
    for (const Word& w : block_.words) {
        if (w.letter == 'G' || w.letter == 'M' || (w.letter == 'T' && !tool_word_is_param)) {
            if (n_commands == 16) fail(w.column, "more than 16 commands on one line");
            const double scaled = w.value * 10.0;
            if (std::abs(scaled - std::round(scaled)) > 1e-6) fail(w.column, std::string("command ") + w.letter + " has more than one decimal");
            commands[n_commands++] = {w.letter, int(std::lround(scaled)), w.column};
            tool_word_is_param = w.letter == 'M' && m_takes_tool(commands[n_commands - 1].code10);
            continue;
        }
        char letter = w.letter;
        if (letter == options_.extruder_letter) letter = 'E';
        else if (letter == 'E' && options_.extruder_letter != 'E')
            fail(w.column, std::string("word E on a file whose extrusion letter is ") + options_.extruder_letter);
        if (find(letter)) fail(w.column, std::string("word ") + w.letter + " appears twice on this line");
        params_.push_back({letter, w.value, w.column, w.has_value, w.text});
    }

    // G43.4/G43.5 H<n>: the tool length offset register of ISO controls. The tool length is the
    // machine file's, so the word is accepted and not used.
    for (std::size_t i = 0; i < n_commands; ++i) {
        if (commands[i].letter != 'G' || (commands[i].code10 != 434 && commands[i].code10 != 435)) continue;
        for (auto it = params_.begin(); it != params_.end(); ++it)
            if (it->letter == 'H') {
                params_.erase(it);
                break;
            }
    }

    // Mode-only codes run first, in RS274's order; then the line's command. (Insertion sort:
    // a line has a handful of commands, and std::stable_sort would allocate.)
    auto before = [](const Command& a, const Command& b) {
        const bool ma = a.letter == 'G' && is_modal_only(a.code10), mb = b.letter == 'G' && is_modal_only(b.code10);
        if (ma != mb) return ma;
        return ma && modal_rank(a.code10) < modal_rank(b.code10);
    };
    for (std::size_t i = 1; i < n_commands; ++i)
        for (std::size_t k = i; k > 0 && before(commands[k], commands[k - 1]); --k) std::swap(commands[k], commands[k - 1]);

    // At most one command on a line may own the words.
    const Command* owner = nullptr;
    std::size_t owners = 0;
    for (std::size_t i = 0; i < n_commands; ++i) {
        const Command& c = commands[i];
        if (c.letter == 'G' && is_modal_only(c.code10)) continue;
        if (++owners == 2 && !params_.empty())
            fail(c.column, "two commands on this line take words: put them on separate lines");
        owner = &c;
    }
    const bool alone = n_commands == 1;
    Command implicit{'G', 0, params_.empty() ? 1u : params_.front().column};
    if (!owner && !params_.empty()) {
        // Axis words with no command continue the modal motion (RS274; CNC files rely on it).
        if (modes_.motion < 0) fail(implicit.column, "axis words without a motion command (G0 or G1)");
        implicit.code10 = modes_.motion * 10;
    }

    // Nothing is written until the whole line has been understood and solved: an error leaves
    // neither output nor state changed by this line.
    const std::size_t out_start = out.size();
    q_saved_.assign(q_.begin(), q_.end());
    const Pose pose_saved = pose_;
    const auto offset_saved = offset_;
    const bool tip_known_saved = tip_known_;
    const auto mode_saved = mode_;
    const auto modes_saved = modes_;
    const auto image_saved = image_;
    try {
        for (std::size_t i = 0; i < n_commands; ++i)
            if (commands[i].letter == 'G' && is_modal_only(commands[i].code10))
                apply_modal(commands[i].code10, commands[i].column, out);
        for (std::size_t i = 0; i < n_commands; ++i)
            if (!(commands[i].letter == 'G' && is_modal_only(commands[i].code10)))
                run_command(commands[i].letter, commands[i].code10, commands[i].column, block_.body, alone, out);
        if (!owner && !params_.empty()) run_command('G', implicit.code10, implicit.column, block_.body, false, out);
    } catch (...) {
        // Nothing of a failed line stays: output, joints, pose, modes.
        out.resize(out_start);
        q_.assign(q_saved_.begin(), q_saved_.end());
        pose_ = pose_saved;
        offset_ = offset_saved;
        tip_known_ = tip_known_saved;
        mode_ = mode_saved;
        modes_ = modes_saved;
        image_ = image_saved;
        emitter_.invalidate(q_);
        try {
            throw;
        } catch (const LineError& e) {
            // A stage below the interpreter refused (e.g. outside a compensation table).
            throw InputError(options_.input_name, line_no_, e.column(), e.what());
        }
    }
}

void Translator::feed(std::string_view line, std::uint64_t line_no, std::string& out) {
    if (lookback_ == 0 || options_.inverse) {
        feed_line(line, line_no, out);
        return;
    }
    save(before_line_);
    const std::size_t held_start = held_.size(), moves_start = pending_.size();
    try {
        feed_line(line, line_no, held_);
    } catch (const InputError& e) {
        if (!line_hit_limit_) throw;
        const bool had_checkpoint = have_checkpoint_;
        if (!unwind_before(line, line_no)) {
            std::string message = e.message();
            if (had_checkpoint)
                message += "; turning it back on the travel move at line " + std::to_string(checkpoint_line_) +
                           " does not keep the printing from there to here within the limits: add a travel move (G0, or G1 "
                           "without E) nearer this line, where the joint can turn back, or plan the path within the limits";
            else
                message += "; there is no travel move (G0, or G1 without E) within the " + std::to_string(lookback_) +
                           " lines before this one to turn the joint back on: add one before this line, or plan the path "
                           "within the limits";
            throw InputError(e.file(), e.line(), e.column(), message);
        }
    }
    if (line_travels_) {
        // A travel move: the next checkpoint. What came before it is final.
        release(held_start, moves_start, out);
        checkpoint_.q = before_line_.q;
        checkpoint_.sent_q = before_line_.sent_q;
        checkpoint_.pose = before_line_.pose;
        checkpoint_.offset = before_line_.offset;
        checkpoint_.tip_known = before_line_.tip_known;
        checkpoint_.mode = before_line_.mode;
        checkpoint_.modes = before_line_.modes;
        checkpoint_.image = before_line_.image;
        checkpoint_.emitter = before_line_.emitter;
        have_checkpoint_ = true;
        checkpoint_line_ = line_no;
        chosen_ = -1;
        window_text_.clear();
        window_lines_.clear();
    }
    if (have_checkpoint_) {
        window_text_.append(line);
        window_text_ += '\n';
        window_lines_.push_back(line_no);
    }
    // Memory stays bounded: past the window (or a few MB of output) the held lines are final.
    constexpr std::size_t kMaxHeldBytes = std::size_t(8) << 20;
    if (!have_checkpoint_ || window_lines_.size() > lookback_ || held_.size() > kMaxHeldBytes) {
        release(held_.size(), pending_.size(), out);
        have_checkpoint_ = false;
        window_text_.clear();
        window_lines_.clear();
    }
}

void Translator::finish(std::string& out) {
    release(held_.size(), pending_.size(), out);
    have_checkpoint_ = false;
    window_text_.clear();
    window_lines_.clear();
}

// The line at line_no runs a joint past its limit: translate the window again from the
// checkpoint, its travel move ending on each other solution of its pose in turn (nearest
// first), until the window and this line fit. On failure everything is as before.
bool Translator::unwind_before(std::string_view line, std::uint64_t line_no) {
    if (!have_checkpoint_ || window_lines_.empty()) return false;
    const std::string held_saved = held_;
    const std::vector<PendingMove> pending_saved = pending_;
    const std::vector<std::pair<char, double>> travel_saved = pending_travel_;
    const int was = chosen_;
    for (int k = 0; k < 64; ++k) {
        if (k == was) continue;
        restore(checkpoint_);
        held_.clear();
        pending_.clear();
        pending_travel_.clear();
        forced_ = k;
        forced_missing_ = false;
        bool ok = true;
        try {
            std::size_t at = 0;
            for (const std::uint64_t no : window_lines_) {
                const std::size_t nl = window_text_.find('\n', at);
                feed_line(std::string_view(window_text_).substr(at, nl - at), no, held_);
                forced_ = -1;
                at = nl + 1;
            }
            feed_line(line, line_no, held_);
        } catch (const InputError&) {
            ok = false;
        }
        forced_ = -1;
        if (ok) {
            chosen_ = k;
            return true;
        }
        if (forced_missing_) break;
    }
    restore(before_line_);
    held_ = held_saved;
    pending_ = pending_saved;
    pending_travel_ = travel_saved;
    return false;
}

void Translator::release(std::size_t bytes, std::size_t moves, std::string& out) {
    out.append(held_, 0, bytes);
    held_.erase(0, bytes);
    if (moves == 0) return;
    const std::size_t travel_end = pending_[moves - 1].travel_end;
    for (std::size_t i = 0, t = 0; i < moves; ++i) {
        const PendingMove& m = pending_[i];
        options_.report->add_move(m.line, m.tip, m.angle, m.feed, m.pieces);
        for (; t < m.travel_end; ++t) options_.report->add_rotary_travel(pending_travel_[t].first, pending_travel_[t].second);
    }
    pending_.erase(pending_.begin(), pending_.begin() + std::ptrdiff_t(moves));
    pending_travel_.erase(pending_travel_.begin(), pending_travel_.begin() + std::ptrdiff_t(travel_end));
    for (PendingMove& m : pending_) m.travel_end -= travel_end;
}

void Translator::report_move(const MoveResult& m) {
    const bool hold = lookback_ > 0 && !options_.inverse;
    for (std::size_t j = 0; j < m.travel.size(); ++j) {
        if (!machine_.joints[j].rotary) continue;
        if (hold) pending_travel_.emplace_back(machine_.joints[j].name, m.travel[j]);
        else options_.report->add_rotary_travel(machine_.joints[j].name, m.travel[j]);
    }
    if (hold) pending_.push_back({line_no_, m.tip_error, m.angle_error, m.feed_error, m.pieces, pending_travel_.size()});
    else options_.report->add_move(line_no_, m.tip_error, m.angle_error, m.feed_error, m.pieces);
}

void Translator::save(Snapshot& s) const {
    s.q.assign(q_.begin(), q_.end());
    s.sent_q.assign(sent_q_.begin(), sent_q_.end());
    s.pose = pose_;
    s.offset = offset_;
    s.tip_known = tip_known_;
    s.mode = mode_;
    s.modes = modes_;
    s.image = image_;
    s.emitter = emitter_;  // everything it remembers of the firmware
}

void Translator::restore(const Snapshot& s) {
    q_.assign(s.q.begin(), s.q.end());
    sent_q_.assign(s.sent_q.begin(), s.sent_q.end());
    pose_ = s.pose;
    offset_ = s.offset;
    tip_known_ = s.tip_known;
    mode_ = s.mode;
    modes_ = s.modes;
    image_ = s.image;
    emitter_ = s.emitter;
}

void Translator::map_angles(const AngleImage& image, const std::vector<double>& a, std::vector<double>& q) const {
    const auto& rot = kin_.rotary_joints();
    for (std::size_t k = 0; k < rot.size(); ++k) {
        const std::size_t j = std::size_t(rot[k]);
        q[j] = image.sign[k] * a[j] + image.shift[k];
    }
}

void Translator::unmap_angles(const AngleImage& image, const std::vector<double>& q, std::vector<double>& a) const {
    const auto& rot = kin_.rotary_joints();
    for (std::size_t k = 0; k < rot.size(); ++k) {
        const std::size_t j = std::size_t(rot[k]);
        a[j] = (q[j] - image.shift[k]) * image.sign[k];
    }
}

// Where else a travel move to `end` may stop: every solution of that pose inside the limits
// other than `usual` (the continuous one), nearest the current joints first. Under G43.4 each is
// an image of the programmed angles (another turn, or the flipped branch), so the moves after it
// keep their programmed interpolation.
void Translator::end_candidates(const Pose& end, const std::vector<double>& programmed, const std::vector<double>& usual) {
    candidates_.clear();
    const auto& rot = kin_.rotary_joints();
    if (rot.empty()) return;
    auto same = [&](const std::vector<double>& a, const std::vector<double>& b) {
        for (const int j : rot)
            if (std::abs(a[std::size_t(j)] - b[std::size_t(j)]) > 1e-6) return false;
        return true;
    };
    std::vector<double> q;
    auto consider = [&](const AngleImage& image) {
        if (!kin_.solve_position(end.tip, q).ok() || !kin_.check_limits(q).ok() || same(q, usual)) return;
        for (const Candidate& c : candidates_)
            if (same(c.q, q)) return;
        candidates_.push_back({q, image});
    };
    const int turns1 = rot.size() > 1 ? 2 : 0;
    if (mode_ == OrientationMode::Angles) {
        for (const bool flip : {false, true}) {
            if (flip && !kin_.has_flip()) continue;
            AngleImage base;
            base.sign[1] = flip ? -1 : 1;
            base.shift[0] = flip ? 180 : 0;
            // Turns counted from the one nearest the current joints.
            double centre[2];
            for (std::size_t k = 0; k < rot.size(); ++k) {
                const std::size_t j = std::size_t(rot[k]);
                centre[k] = std::round((q_[j] - (base.sign[k] * programmed[j] + base.shift[k])) / 360.0);
            }
            for (int t0 = -2; t0 <= 2; ++t0)
                for (int t1 = -turns1; t1 <= turns1; ++t1) {
                    AngleImage image = base;
                    image.shift[0] += 360.0 * (centre[0] + t0);
                    if (rot.size() > 1) image.shift[1] += 360.0 * (centre[1] + t1);
                    q = usual;
                    map_angles(image, programmed, q);
                    consider(image);
                }
        }
    } else {
        const auto solutions = kin_.orientation_solutions(end.axis);
        for (int b = 0; b < solutions.count; ++b)
            for (int t0 = -2; t0 <= 2; ++t0)
                for (int t1 = -turns1; t1 <= turns1; ++t1) {
                    q = usual;
                    for (std::size_t k = 0; k < rot.size(); ++k) {
                        const std::size_t j = std::size_t(rot[k]);
                        const double sol = solutions.angle[b][k];
                        if (std::isnan(sol)) continue;  // free at a pole: it stays
                        q[j] = q_[j] + wrap180(sol - q_[j]) + 360.0 * (k == 0 ? t0 : t1);
                    }
                    consider(image_);
                }
    }
    auto distance = [&](const Candidate& c) {
        double d = 0;
        for (const int j : rot) d += (c.q[std::size_t(j)] - q_[std::size_t(j)]) * (c.q[std::size_t(j)] - q_[std::size_t(j)]);
        return d;
    };
    std::stable_sort(candidates_.begin(), candidates_.end(), [&](const Candidate& a, const Candidate& b) { return distance(a) < distance(b); });
}

void Translator::apply_modal(int code10, std::uint32_t column, std::string& out) {
    switch (code10) {
        case 200:
        case 210:
            // xlate5 converts to millimetres itself; the firmware always works in mm.
            modes_.inches = code10 == 200;
            out += "G21\n";
            return;
        case 170:
        case 180:
        case 190:
            // The arc plane: xlate5 linearises arcs under tool-centre-point control itself.
            modes_.plane = code10 / 10;
            if (mode_ == OrientationMode::Joints) {
                passthrough('G', code10, {}, false, out);
                emitter_.feed_mode_sent(modes_.inverse_time);
            }
            return;
        case 434:
        case 435:
        case 490:
            if (options_.inverse) fail(column, "joint-space input has no G43.4/G43.5/G49");
        {
            const OrientationMode mode = code10 == 434 ? OrientationMode::Angles : code10 == 435 ? OrientationMode::Vector : OrientationMode::Joints;
            if (mode != mode_) image_ = {};  // entering G43.4: its angles mean the joints as they are
            mode_ = mode;
        }
            return;
        case 900:
        case 910:
            // Joint targets are always written absolute; E keeps the input's mode, stated
            // explicitly because firmwares differ on whether G90/G91 change it.
            modes_.absolute = code10 == 900;
            modes_.e_relative = code10 == 910;
            out += modes_.e_relative ? "G90\nM83\n" : "G90\nM82\n";
            return;
        case 930:
        case 940:
            // Under tool-centre-point control xlate5 computes every F itself (mm/min), so the
            // input's feed mode is understood here and not sent; in joint space it is passed on.
            modes_.inverse_time = code10 == 930;
            if (mode_ == OrientationMode::Joints) {
                passthrough('G', code10, {}, false, out);
                emitter_.feed_mode_sent(modes_.inverse_time);
            }
            (void)column;
            return;
        default:
            passthrough('G', code10, {}, false, out);
            return;
    }
}

void Translator::passthrough(char letter, int code10, std::string_view body, bool alone, std::string& out) const {
    if (alone) {
        out += body;
        out += '\n';
        return;
    }
    append_code(out, letter, code10);
    if (!(letter == 'G' && is_modal_only(code10))) {
        for (const auto& p : params_) {
            out += ' ';
            out += p.letter;
            if (p.has_value) append_shortest(out, p.value);
        }
    }
    out += '\n';
}

void Translator::run_command(char letter, int code10, std::uint32_t column, std::string_view body, bool alone,
                             std::string& out) {
    if (letter == 'M') {
        if (code10 == 820) modes_.e_relative = false;
        if (code10 == 830) modes_.e_relative = true;
        passthrough(letter, code10, body, alone, out);
        return;
    }
    if (letter == 'T') {
        passthrough(letter, code10, body, alone, out);
        return;
    }
    switch (code10) {
        case 0:
        case 10:
            modes_.motion = code10 / 10;
            if (mode_ == OrientationMode::Joints) move_joints(code10 / 10, column, out);
            else move(code10 / 10, column, out);
            return;
        case 20:
        case 30:
            modes_.motion = code10 / 10;
            if (mode_ != OrientationMode::Joints) {
                arc(code10 == 20, column, out);
                return;
            }
            if (!modes_.absolute || modes_.inches)
                fail(column, "joint-space arcs are passed on only in G90 and G21 (millimetres)");
            if (options_.inverse) fail(column, "joint-space arcs cannot be turned back into tool space");
            for (const auto& p : params_) {
                const int j = joint_of(p.letter);
                if (j >= 0) q_[std::size_t(j)] = number(p);
            }
            pose_ = kin_.forward(q_);
            emitter_.invalidate(q_);
            passthrough('G', code10, body, alone, out);
            return;
        case 280:
            home(out);
            return;
        case 920:
            set_position(column, out);
            return;
        default:
            for (const auto& p : params_) {
                if (!is_axis_letter(p.letter)) continue;
                if (mode_ != OrientationMode::Joints) {
                    std::string code;
                    append_code(code, 'G', code10);
                    fail(column, code + " with axis words is not supported under tool-centre-point control "
                                        "(switch to G49 to send it as joint values)");
                }
                emitter_.invalidate(q_);  // the firmware moves somewhere xlate5 cannot follow
            }
            passthrough('G', code10, body, alone, out);
            return;
    }
}

void Translator::move(int gcode, std::uint32_t column, std::string& out) {
    const double unit = modes_.unit();
    Eigen::Vector3d tip = pose_.tip - offset_;  // program frame
    Eigen::Vector3d ijk = Eigen::Vector3d::Zero();
    bool any_xyz = false, any_ijk = false, any_rotary = false;
    std::uint32_t ijk_column = column;
    std::optional<PassedNumber> e, f;
    q_next_ = q_;
    commanded_.assign(q_.size(), false);
    // Under G43.4 the rotary words are programmed angles; the joints are their image.
    angles_.assign(q_.begin(), q_.end());
    unmap_angles(image_, q_, angles_);
    for (const Param& p : params_) {
        switch (p.letter) {
            case 'X': case 'Y': case 'Z': {
                const int i = p.letter - 'X';
                const double v = number(p) * unit;
                tip[i] = modes_.absolute ? v : tip[i] + v;
                any_xyz = true;
                break;
            }
            case 'I': case 'J': case 'K':
                if (mode_ != OrientationMode::Vector)
                    fail(p.column, "I J K give a tool vector only under G43.5");
                if (!any_ijk) ijk_column = p.column;
                ijk[p.letter - 'I'] = number(p);
                any_ijk = true;
                break;
            case 'E': e = passed(p); break;
            case 'F':
                f = passed(p);
                if (!(f->value > 0)) fail(p.column, "feed rate F must be positive");
                break;
            default: {
                const int j = joint_of(p.letter);
                if (j < 0 || !machine_.joints[std::size_t(j)].rotary)
                    fail(p.column, std::string("word ") + p.letter + " is not a tool-space word for machine " + machine_.name +
                                       " (X Y Z give the tip" + (mode_ == OrientationMode::Vector ? ", I J K the tool axis)" : ", its rotary letters the orientation)"));
                if (mode_ == OrientationMode::Vector)
                    fail(p.column, std::string("rotary word ") + p.letter + " under G43.5: give the tool axis as I J K, or switch to G43.4");
                const double v = number(p);
                angles_[std::size_t(j)] = modes_.absolute ? v : angles_[std::size_t(j)] + v;
                commanded_[std::size_t(j)] = true;
                any_rotary = true;
                break;
            }
        }
    }
    if (any_rotary) map_angles(image_, angles_, q_next_);
    Eigen::Vector3d axis = pose_.axis;
    if (any_ijk) {
        if (!(ijk.norm() > 1e-12)) fail(ijk_column, "tool vector I J K has length 0");
        axis = ijk.normalized();
    }
    IkResult r;
    if (any_ijk) r = kin_.solve_orientation(axis, q_, q_next_);
    Pose next = pose_;
    if (r.ok()) {
        if (!any_xyz && !tip_known_) {
            // Before the program has placed the tip (start, after G28) a rotary-only move turns
            // the rotaries and leaves the linear joints, as the start code of seed 001 expects.
            next = kin_.forward(q_next_);
        } else {
            next.tip = tip + offset_;
            r = kin_.solve_position(next.tip, q_next_, any_rotary ? &next.axis : nullptr);
            if (any_ijk) next.axis = axis;
        }
    }
    if (r.ok()) r = kin_.check_limits(q_next_);
    // A travel move (tool space, no extrusion) may end on another solution of its pose: when its
    // usual end is outside a joint's limits, or when the look-back replays it to unwind a joint
    // for the printing that follows. Printing moves never change solution: their path is printed.
    const bool tool_space = mode_ != OrientationMode::Joints && (any_xyz || tip_known_);
    const bool prints = e && (modes_.e_relative ? e->value != 0 : e->value != modes_.e_position);
    const bool travel = tool_space && !prints && (any_xyz || any_rotary || any_ijk);
    line_travels_ = line_travels_ || travel;
    bool unwind = false;
    const int forced = travel ? forced_ : -1;
    if (travel) forced_ = -1;
    if (travel && (forced >= 0 || (!r.ok() && r.status == IkStatus::OutOfLimits))) {
        end_candidates(next, angles_, q_next_);
        const std::size_t k = forced >= 0 ? std::size_t(forced) : 0;
        if (k < candidates_.size()) {
            q_next_ = candidates_[k].q;
            if (mode_ == OrientationMode::Angles) image_ = candidates_[k].image;
            unwind = true;
            r = {};
        } else if (forced >= 0) {
            forced_missing_ = true;
            fail(column, "no other solution of this pose inside the limits");
        }
    }
    if (!r.ok()) {
        line_hit_limit_ = r.status == IkStatus::OutOfLimits;
        if (r.status == IkStatus::OutOfLimits && lookback_ == 0)
            r.message += "; turn the joint back on a travel move before this line, or plan the path within the limits";
        fail(column, r.message);
    }
    for (std::size_t j = 0; j < q_.size(); ++j) {
        const bool rotary = machine_.joints[j].rotary;
        if ((!rotary && any_xyz) || (rotary && any_ijk)) commanded_[j] = true;
    }
    if (f && !modes_.inverse_time) modes_.feed = f->value;
    if (modes_.inverse_time && !f && (any_xyz || any_rotary || any_ijk))
        fail(column, "under G93 every move needs its F (1/minutes)");
    MoveSpec spec;
    spec.gcode = gcode;
    // Before the program has placed the tip, the move is a joint move (one piece, F as written).
    spec.mode = (!any_xyz && !tip_known_) ? OrientationMode::Joints : mode_;
    spec.q0 = &q_;
    spec.p0 = pose_;
    spec.q1 = &q_next_;
    spec.p1 = next;
    spec.commanded = &commanded_;
    spec.e = e;
    spec.e_relative = modes_.e_relative;
    spec.e_start = modes_.e_position;
    spec.feed = modes_.feed;
    spec.f = f;
    spec.inverse_time = modes_.inverse_time && f ? f->value : 0.0;
    // An unwinding travel move turns the rotaries linearly from their start to the chosen end
    // (angle form) while the split holds the tip on the straight travel line, rather than
    // reorienting in place at one end: the tip never leaves the path the slicer planned for it
    // (usually lifted clear of the part), no end of a printed bead gets a hot nozzle sweeping
    // round on it, and each rotary moves monotonically between two values inside its limits.
    // For a branch flip (rw2: A by 180 degrees, B to -B) the tool passes upright (B = 0) on the
    // way instead of sweeping a full turn at its printing tilt.
    if (unwind) spec.mode = OrientationMode::Angles;
    MoveResult* measured = options_.report && spec.mode != OrientationMode::Joints ? &move_result_ : nullptr;
    auto res = motion_.emit(spec, out, measured);
    if (!res.ok() && res.status == IkStatus::OutOfLimits && travel && !unwind && spec.mode == OrientationMode::Vector) {
        // The continuous path of this travel move leaves the limits, though its end (the
        // solution nearest the start inside them) does not: turn there in angle form instead.
        spec.mode = OrientationMode::Angles;
        unwind = true;
        res = motion_.emit(spec, out, measured);
    }
    if (!res.ok()) {
        line_hit_limit_ = res.status == IkStatus::OutOfLimits;
        if (res.status == IkStatus::OutOfLimits && lookback_ == 0)
            res.message += "; turn the joint back on a travel move before this line, or plan the path within the limits";
        fail(column, res.message);
    }
    if (measured) report_move(*measured);
    if (spec.mode == OrientationMode::Vector) q_next_ = motion_.final_joints();
    // An unbounded rotary that has wound far from zero is re-zeroed at the end of a travel move
    // (no extrusion), where a G92 cannot disturb a printed line: firmware without wrapping
    // (Marlin, soft endstops) then never runs out of range.
    if (!e || e->value == 0) {
        for (std::size_t j = 0; j < q_next_.size(); ++j) {
            const Joint& J = machine_.joints[j];
            if (J.rezero_beyond <= 0 || std::abs(q_next_[j]) <= J.rezero_beyond) continue;
            const double turns = std::round(q_next_[j] / 360.0);
            std::vector<bool> which(q_next_.size(), false);
            which[j] = true;
            q_next_[j] -= 360.0 * turns;
            emitter_.set_position(out, q_next_, which, std::nullopt);
        }
    }
    q_.swap(q_next_);
    pose_ = next;
    tip_known_ = tip_known_ || any_xyz;
    track_extrusion(e);
}

void Translator::track_extrusion(const std::optional<PassedNumber>& e) {
    if (!e) return;
    modes_.e_position = modes_.e_relative ? modes_.e_position + e->value : e->value;
}

void Translator::move_joints(int gcode, std::uint32_t /*column*/, std::string& out) {
    const double unit = modes_.unit();
    std::optional<PassedNumber> e, f;
    bool any_linear = false;
    // The inverse works on what the firmware was sent; words left out keep their sent value.
    q_next_ = options_.inverse ? sent_q_ : q_;
    commanded_.assign(q_.size(), false);
    for (const Param& p : params_) {
        switch (p.letter) {
            case 'E': e = passed(p); break;
            case 'F':
                f = passed(p);
                if (!(f->value > 0)) fail(p.column, "feed rate F must be positive");
                break;
            case 'I': case 'J': case 'K':
                fail(p.column, "I J K are tool-vector words (G43.5); under G49 the words are joint values");
            default: {
                const int j = joint_of(p.letter);
                if (j < 0) fail(p.column, std::string("word ") + p.letter + " is not a joint of machine " + machine_.name);
                const bool rotary = machine_.joints[std::size_t(j)].rotary;
                const double v = number(p) * (rotary ? 1.0 : unit);
                q_next_[std::size_t(j)] = modes_.absolute ? v : q_[std::size_t(j)] + v;
                commanded_[std::size_t(j)] = true;
                any_linear = any_linear || !rotary;
                break;
            }
        }
    }
    // The inverse reads what the firmware was sent: measured errors are added back first.
    if (options_.inverse) {
        sent_q_ = q_next_;
        machine_.compensation.undo(q_next_);
    }
    if (auto r = kin_.check_limits(q_next_); !r.ok()) fail(params_.empty() ? 1 : params_.front().column, r.message);
    q_.swap(q_next_);
    pose_ = kin_.forward(q_);
    tip_known_ = tip_known_ || any_linear;
    if (options_.inverse) tool_emitter_.move(out, gcode, pose_.tip, pose_.axis, q_, e, f);
    else emitter_.move(out, gcode, q_, commanded_, e, f, modes_.inverse_time);  // under G93 every move keeps its F
    track_extrusion(e);
}

void Translator::set_position(std::uint32_t column, std::string& out) {
    if (params_.empty()) {
        passthrough('G', 920, block_.body, true, out);
        return;
    }
    const double unit = modes_.unit();
    std::vector<bool> which(q_.size(), false);
    std::optional<PassedNumber> e;
    bool any_rotary = false;
    for (const Param& p : params_) {
        if (p.letter == 'E') {
            e = passed(p);
            modes_.e_position = e->value;
            continue;
        }
        const bool tip_word = mode_ != OrientationMode::Joints && (p.letter == 'X' || p.letter == 'Y' || p.letter == 'Z');
        if (tip_word) continue;  // applied below, after the joints
        const int j = joint_of(p.letter);
        if (j < 0 || (mode_ != OrientationMode::Joints && !machine_.joints[std::size_t(j)].rotary))
            fail(p.column, std::string("G92 word ") + p.letter + " is not a joint of machine " + machine_.name);
        const bool rotary = machine_.joints[std::size_t(j)].rotary;
        q_[std::size_t(j)] = number(p) * (rotary ? 1.0 : unit);
        sent_q_[std::size_t(j)] = q_[std::size_t(j)];
        which[std::size_t(j)] = true;
        any_rotary = any_rotary || rotary;
        image_ = {};  // the program and the firmware now agree on the joint
    }
    // The machine did not move: its true pose follows from the joints it now says it is at.
    if (mode_ == OrientationMode::Joints || any_rotary) pose_ = kin_.forward(q_);
    if (mode_ != OrientationMode::Joints) {
        // Under tool-centre-point control G92 X Y Z shifts the program frame, and is not sent.
        for (const Param& p : params_) {
            if (p.letter != 'X' && p.letter != 'Y' && p.letter != 'Z') continue;
            const int i = p.letter - 'X';
            offset_[i] = pose_.tip[i] - number(p) * unit;
            tip_known_ = true;
        }
    }
    (void)column;
    if (options_.inverse) {
        // Tool space has a word for a rotary reset only; a linear one just changes the tip.
        std::string line = "G92";
        for (std::size_t j = 0; j < which.size(); ++j) {
            if (!which[j] || !machine_.joints[j].rotary) continue;
            line += ' ';
            line += machine_.joints[j].name;
            append_fixed(line, q_[j], machine_.dialect.rotary_decimals + 2);
        }
        if (e) {
            line += " E";
            append_passed(line, *e);
        }
        if (line.size() > 3) out += line + '\n';
        tool_emitter_.invalidate();
        return;
    }
    emitter_.set_position(out, q_, which, e);
}

void Translator::home(std::string& out) {
    std::vector<bool> which(q_.size(), params_.empty());
    for (const Param& p : params_) {
        const int j = joint_of(p.letter);
        if (j < 0) fail(p.column, std::string("G28 word ") + p.letter + " is not a joint of machine " + machine_.name);
        which[std::size_t(j)] = true;
    }
    for (std::size_t j = 0; j < q_.size(); ++j)
        if (which[j]) q_[j] = machine_.joints[j].home;
    out += "G28";
    for (const Param& p : params_) {
        const Joint& j = machine_.joints[std::size_t(joint_of(p.letter))];
        out += ' ';
        out += options_.inverse ? j.name : j.output;
    }
    out += '\n';
    offset_.setZero();
    image_ = {};
    tip_known_ = false;
    sent_q_ = q_;
    pose_ = kin_.forward(q_);
    emitter_.invalidate(q_);
    tool_emitter_.invalidate();
}

}  // namespace xlate5

namespace xlate5 {

// G2/G3 under tool-centre-point control: the arc (I J K centre or R radius, any plane, helical
// along the plane's normal, P full turns) is cut into chords within half the tolerance in tool
// space; each chord is then a move like any other, so the motion stage bounds the rest.
void Translator::arc(bool clockwise, std::uint32_t column, std::string& out) {
    const double unit = modes_.unit();
    // Plane axes (a, b) and normal n: G17 XY, G18 ZX, G19 YZ (RS274), with the centre words.
    int a = 0, b = 1, n = 2;
    char ca = 'I', cb = 'J';
    if (modes_.plane == 18) a = 2, b = 0, n = 1, ca = 'K', cb = 'I';
    if (modes_.plane == 19) a = 1, b = 2, n = 0, ca = 'J', cb = 'K';
    const Eigen::Vector3d start = pose_.tip - offset_;
    Eigen::Vector3d end = start;
    double off_a = 0, off_b = 0, radius = 0;
    bool centre = false, by_radius = false;
    int turns = 1;
    std::vector<Param> rotary_words, other;
    std::optional<Param> e_word, f_word;
    for (const Param& p : params_) {
        switch (p.letter) {
            case 'X': case 'Y': case 'Z': {
                const int i = p.letter - 'X';
                const double v = number(p) * unit;
                end[i] = modes_.absolute ? v : start[i] + v;
                break;
            }
            case 'I': case 'J': case 'K':
                if (p.letter == ca) off_a = number(p) * unit, centre = true;
                else if (p.letter == cb) off_b = number(p) * unit, centre = true;
                else fail(p.column, std::string("word ") + p.letter + " is not a centre offset in this arc plane");
                break;
            case 'R': radius = number(p) * unit, by_radius = true; break;
            case 'P': {
                const double v = number(p);
                if (v < 1 || v != std::floor(v)) fail(p.column, "P (turns) must be a whole number >= 1");
                turns = int(v);
                break;
            }
            case 'E': e_word = p; break;
            case 'F': f_word = p; break;
            default: {
                const int j = joint_of(p.letter);
                if (j < 0 || !machine_.joints[std::size_t(j)].rotary || mode_ != OrientationMode::Angles)
                    fail(p.column, std::string("word ") + p.letter + " is not understood on an arc here");
                rotary_words.push_back(p);
            }
        }
    }
    if (centre == by_radius) fail(column, "an arc needs its centre as I J K offsets or its radius as R (one of them)");
    const Eigen::Vector2d s2(start[a], start[b]), e2(end[a], end[b]);
    Eigen::Vector2d c2;
    if (centre) {
        c2 = s2 + Eigen::Vector2d(off_a, off_b);
    } else {
        // R > 0: the shorter arc, R < 0: the longer; the centre lies on the chord's bisector.
        const Eigen::Vector2d chord = e2 - s2;
        const double d = chord.norm();
        if (d == 0 || std::abs(radius) < d / 2 - 1e-9) fail(column, "arc radius R is too small for the distance to the end point");
        const double h = std::sqrt(std::max(0.0, radius * radius - d * d / 4));
        const Eigen::Vector2d mid = 0.5 * (s2 + e2), left(-chord.y() / d, chord.x() / d);
        // For G2 (clockwise) with R > 0 the centre is on the right of the chord.
        const double side = ((clockwise ? -1.0 : 1.0) * (radius > 0 ? 1.0 : -1.0));
        c2 = mid + side * h * left;
    }
    const double r0 = (s2 - c2).norm(), r1 = (e2 - c2).norm();
    if (!(r0 > 1e-9)) fail(column, "arc radius is 0");
    if (std::abs(r0 - r1) > 0.01 + 1e-3 * r0)
        fail(column, "the arc's end point is not on its circle (radius " + std::to_string(r0) + " at the start, " + std::to_string(r1) +
                         " at the end)");
    const double t0 = std::atan2(s2.y() - c2.y(), s2.x() - c2.x()), t1 = std::atan2(e2.y() - c2.y(), e2.x() - c2.x());
    constexpr double kTwoPi = 6.283185307179586;
    double sweep = clockwise ? t0 - t1 : t1 - t0;
    while (sweep <= 1e-12) sweep += kTwoPi;  // equal ends: a full circle
    sweep += kTwoPi * (turns - 1);
    // Chords within half the tolerance, the other half left for the joint-space split.
    const double chord_tol = 0.5 * machine_.motion.tolerance;
    const double step = chord_tol < r0 ? 2 * std::acos(1 - chord_tol / r0) : kTwoPi / 4;
    const int chords = std::max(1, int(std::ceil(sweep / step)));

    // Each chord runs through move() as an absolute, metric G1 with its own words.
    const Modes saved = modes_;
    std::vector<double> q_start = q_;
    unmap_angles(image_, q_, q_start);  // rotary words are programmed angles
    const double e_total = e_word ? number(*e_word) * unit : 0.0;
    const double e0 = modes_.e_position;
    const std::vector<Param> original = params_;
    for (int k = 1; k <= chords; ++k) {
        const double f = double(k) / chords;
        const double th = t0 + (clockwise ? -1.0 : 1.0) * sweep * f;
        Eigen::Vector3d p;
        p[a] = c2.x() + r0 * std::cos(th);
        p[b] = c2.y() + r0 * std::sin(th);
        p[n] = start[n] + (end[n] - start[n]) * f;
        if (k == chords) p[a] = end[a], p[b] = end[b];
        params_.clear();
        for (int i = 0; i < 3; ++i) params_.push_back({char('X' + i), p[i], column, true, {}});
        for (const Param& rw : rotary_words) {
            const int j = joint_of(rw.letter);
            const double target = saved.absolute ? number(rw) : q_start[std::size_t(j)] + number(rw);
            params_.push_back({rw.letter, q_start[std::size_t(j)] + (target - q_start[std::size_t(j)]) * f, column, true, {}});
        }
        if (e_word) {
            double v;
            if (saved.e_relative) v = e_total / chords;  // equal chords: equal shares
            else v = e0 + (e_total - e0) * f;
            const bool last = k == chords;
            params_.push_back({'E', last && !saved.e_relative ? number(*e_word) * unit : v, e_word->column, true,
                               last && !saved.e_relative && !saved.inches ? e_word->text : std::string_view{}});
        }
        if (f_word && k == 1) params_.push_back(*f_word);
        modes_.absolute = true;
        modes_.inches = false;
        if (f_word && k == 1 && saved.inches) params_.back().value *= 25.4, params_.back().text = {};
        move(1, column, out);
        modes_.absolute = saved.absolute;
        modes_.inches = saved.inches;
    }
    params_ = original;
    modes_.motion = clockwise ? 2 : 3;
}

}  // namespace xlate5

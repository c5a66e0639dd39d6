// SPDX-License-Identifier: GPL-3.0-or-later
// The manual page: the declarations as troff, between prose sections kept here (stage: command
// line). The build writes it with `xlate5 --man-page` (cli/CMakeLists.txt) and a test renders it
// with man -l and compares its options with --help's.
#include "cli/man_page.hpp"

#include <vector>

namespace xlate5::cli {
namespace {

// Text for troff: a backslash is written \e, and a line may not start with a control character.
std::string esc(const std::string& s) {
    std::string out;
    for (char c : s) out += c == '\\' ? std::string("\\e") : std::string(1, c);
    return out;
}
std::string line(const std::string& s) {
    const std::string e = esc(s);
    return (!e.empty() && (e[0] == '.' || e[0] == '\'')) ? "\\&" + e : e;
}
// An option name: its hyphens as minus signs, so a copied option works in a shell.
std::string flag(const std::string& s) {
    std::string out;
    for (char c : s) out += c == '-' ? std::string("\\-") : std::string(1, c);
    return out;
}

void options_of(const CLI::App& app, std::ostream& out, bool with_help) {
    for (const CLI::Option* o : app.get_options()) {
        if (o->get_group().empty()) continue;  // hidden
        if (!with_help && o->get_lnames() == std::vector<std::string>{"help"}) continue;  // said once, under OPTIONS
        std::string names;
        if (o->get_positional() && o->get_lnames().empty() && o->get_snames().empty()) {
            names = "\\fI" + esc(o->get_name(true)) + "\\fR";
        } else {
            for (const auto& s : o->get_snames()) names += (names.empty() ? "" : ", ") + std::string("\\fB") + flag("-" + s) + "\\fR";
            for (const auto& l : o->get_lnames()) names += (names.empty() ? "" : ", ") + std::string("\\fB") + flag("--" + l) + "\\fR";
            const std::string value = o->get_option_text().empty() ? o->get_type_name() : o->get_option_text();
            if (!value.empty() && o->get_type_size() != 0) names += " \\fI" + esc(value) + "\\fR";
        }
        out << ".TP\n" << names << "\n" << line(o->get_description()) << "\n";
    }
}

void commands_of(const CLI::App& app, const std::string& prefix, std::ostream& out) {
    for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; })) {
        const std::string name = prefix + " " + sub->get_name();
        out << ".SS \"" << esc(name) << "\"\n" << line(sub->get_description()) << ".\n";
        options_of(*sub, out, false);
        commands_of(*sub, name, out);
    }
}

}  // namespace

void write_man_page(const CLI::App& app, const std::string& version, std::ostream& out) {
    out << ".\\\" The manual page of xlate5, written by `xlate5 --man-page` from its own option declarations.\n"
        << ".TH XLATE5 1 \"\" \"xlate5 " << esc(version) << "\" \"User Commands\"\n.nh\n";
    out << R"(.SH NAME
xlate5 \- translate tool-space 5-axis G-code into joint-space G-code for a given machine
.SH SYNOPSIS
.B xlate5
.B \-\-machine
.I NAME|PATH
.RB [ \-i
.IR IN ]
.RB [ \-o
.IR OUT ]
.RI [ OPTIONS ]
.br
.B xlate5
.B \-\-machine
.I NAME
.B \-\-inverse
.RI [ OPTIONS ]
.br
.B xlate5 machines
.br
.B xlate5
.RB [ \-\-machine
.IR NAME ]
.B calibrate
.I fit|plate|offset|centre|pivots
.I FILE
.RI [ OPTIONS ]
.br
.B xlate5 serve
.RB ( \-\-machine
.I NAME
|
.B \-\-config
.IR FILE )
.RB ( \-\-port
.I DEVICE
|
.B \-\-printer
.BR sim )
.RI [ OPTIONS ]
.br
.B xlate5 ports
.SH DESCRIPTION
Slicers and CAM programs write vendor-neutral 5-axis G-code: the nozzle tip in the part's frame
plus a tool orientation (rotary angles under G43.4, or an I J K tool vector under G43.5).
Stock Marlin and RepRapFirmware move joints only.
.B xlate5
reads such G-code as a stream, solves each move with the machine's closed-form inverse
kinematics, splits moves so the tip stays within a tolerance of the programmed path, and
writes joint-space G-code for the firmware.
.PP
A machine is one TOML file (see FILES).
Without a subcommand, xlate5 translates standard input (or
.BR \-i )
to standard output (or
.BR \-o ,
written atomically: an error never leaves a half-written file).
.B xlate5 serve
stands between a sender (OctoPrint, Printrun) and the firmware over serial, translating each
line as it comes.
.SH OPTIONS
These translate; the machine options also apply to the commands below, before or after them.
)";
    options_of(app, out, true);
    out << ".SH COMMANDS\n";
    commands_of(app, "xlate5", out);
    out << R"(.SH EXIT STATUS
.TP
.B 0
translated (or the command succeeded)
.TP
.B 1
the G-code cannot be translated: \fIfile\fR:\fIline\fR:\fIcolumn\fR: \fIcause\fR on standard error
.TP
.B 2
bad command line
.TP
.B 3
machine file missing or broken (\fIpath\fR:\fIline\fR: \fIkey\fR: \fIcause\fR), or a \-\-set it does not have
.TP
.B 4
input cannot be read or output cannot be written
.TP
.B 70
internal error (a bug: please report it with the input)
.SH ENVIRONMENT
.TP
.B XLATE5_MACHINES
a directory searched for machine files before all others.
.TP
.B XDG_CONFIG_HOME
the user's configuration directory (default \fI~/.config\fR); machine files are looked up in
its \fIxlate5/machines\fR.
.SH FILES
A machine name given to \-\-machine is looked up, first match first, in:
.TP
.I $XLATE5_MACHINES
when set
.TP
.I $XDG_CONFIG_HOME/xlate5/machines
the user's own machines (\fI~/.config/xlate5/machines\fR when XDG_CONFIG_HOME is not set)
.TP
.I /etc/xlate5/machines
the system's machines (and the service's)
.TP
.I /usr/share/xlate5/machines
the machines shipped with xlate5: \fIPREFIX/share/xlate5/machines\fR beside \fIPREFIX/bin/xlate5\fR
.PP
A name containing a slash or ending in \fI.toml\fR is a path.
.TP
.I /etc/xlate5/PRINTER.toml
the configuration of the service instance \fBxlate5@PRINTER.service\fR (example in
\fI/usr/share/xlate5/xlate5.toml.example\fR).
.SH EXAMPLES
.EX
xlate5 \-\-machine rw2 \-i part.gcode \-o joints.gcode
cat part.gcode | xlate5 \-\-machine rw2 > joints.gcode
xlate5 \-\-machine rw2 \-\-inverse \-i joints.gcode \-o preview.gcode
xlate5 serve \-\-machine rw2 \-\-printer sim \-\-pty /tmp/xlate5/printer
.EE
.SH SEE ALSO
The documentation in \fI/usr/share/doc/xlate5\fR: \%README.md, \%machines.md, \%calibration.md,
\%service.md.
)";
}

}  // namespace xlate5::cli

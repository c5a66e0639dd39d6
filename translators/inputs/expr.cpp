// SPDX-License-Identifier: GPL-3.0-or-later
// Machine parameter expressions, for reading machine files. What it may call: see expr.hpp.
#include "translators/inputs/expr.hpp"

#include <cctype>
#include <cmath>
#include <cstdlib>
#include <stdexcept>
#include <string>

namespace xlate5 {

namespace {

class Parser {
public:
    Parser(const std::string& s, const std::map<std::string, double>& p) : s_(s), params_(p) {
        // Messages quote the expression; a long one is cut, so the message stays readable.
        quoted_ = "\"" + (s_.size() > 60 ? s_.substr(0, 60) + "..." : s_) + "\"";
    }

    double parse() {
        double v = sum();
        skip();
        if (i_ != s_.size()) throw std::invalid_argument("unexpected '" + s_.substr(i_, 1) + "' in " + quoted_);
        if (!std::isfinite(v)) throw std::invalid_argument(quoted_ + " is not a finite number");
        return v;
    }

private:
    void skip() {
        while (i_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[i_]))) ++i_;
    }
    bool eat(char c) {
        skip();
        if (i_ < s_.size() && s_[i_] == c) {
            ++i_;
            return true;
        }
        return false;
    }
    double sum() {
        double v = product();
        for (;;) {
            if (eat('+')) v += product();
            else if (eat('-')) v -= product();
            else return v;
        }
    }
    double product() {
        double v = unary();
        for (;;) {
            if (eat('*')) v *= unary();
            else if (eat('/')) v /= unary();
            else return v;
        }
    }
    // One level deeper for a unary sign or an opening parenthesis, the only ways to recurse.
    struct Level {
        explicit Level(Parser& p) : p_(p) {
            if (++p_.depth_ > kMaxExpressionDepth)
                throw std::invalid_argument("expression nests deeper than " + std::to_string(kMaxExpressionDepth) +
                                            " parentheses or signs in " + p_.quoted_);
        }
        ~Level() { --p_.depth_; }
        Parser& p_;
    };
    double unary() {
        if (eat('-')) {
            Level level(*this);
            return -unary();
        }
        if (eat('+')) {
            Level level(*this);
            return unary();
        }
        return atom();
    }
    double atom() {
        skip();
        if (eat('(')) {
            Level level(*this);
            double v = sum();
            if (!eat(')')) throw std::invalid_argument("missing ')' in " + quoted_);
            return v;
        }
        if (i_ < s_.size() && (std::isdigit(static_cast<unsigned char>(s_[i_])) || s_[i_] == '.')) {
            const char* begin = s_.c_str() + i_;
            char* end = nullptr;
            double v = std::strtod(begin, &end);
            if (end == begin) throw std::invalid_argument("bad number in " + quoted_);
            i_ += std::size_t(end - begin);
            return v;
        }
        const std::size_t start = i_;
        while (i_ < s_.size() && (std::isalnum(static_cast<unsigned char>(s_[i_])) || s_[i_] == '_')) ++i_;
        if (start == i_) throw std::invalid_argument("expected a number or parameter name in " + quoted_);
        const std::string name = s_.substr(start, i_ - start);
        auto it = params_.find(name);
        if (it == params_.end()) throw std::invalid_argument("unknown parameter '" + name + "'");
        return it->second;
    }

    const std::string& s_;
    const std::map<std::string, double>& params_;
    std::size_t i_ = 0;
    int depth_ = 0;
    std::string quoted_;
};

}  // namespace

double evaluate_expression(const std::string& text, const std::map<std::string, double>& params) {
    return Parser(text, params).parse();
}

}  // namespace xlate5

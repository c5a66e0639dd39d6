// SPDX-License-Identifier: GPL-3.0-or-later
#include "daemon/link.hpp"

#include <chrono>

namespace xlate5 {

void Link::start(LineHandler on_line, CloseHandler on_close) {
    on_line_ = std::move(on_line);
    on_close_ = std::move(on_close);
    read();
}

void Link::resume_reading() {
    if (!paused_) return;
    paused_ = false;
    if (open_ && !reading_) read();
}

void Link::read() {
    if (paused_ || reading_) return;
    reading_ = true;
    auto self = shared_from_this();
    read_some(asio::buffer(buffer_), [this, self](boost::system::error_code ec, std::size_t n) {
        reading_ = false;
        if (!open_) return;
        if (ec) {
            if (transient(ec)) {
                if (!hung_up_) {
                    hung_up_ = true;
                    if (on_hangup_) on_hangup_();
                }
                if (present_) {
                    present_ = false;
                    if (on_presence) on_presence(false);
                }
                // Nobody holds the other end: look again shortly (a timer, not a busy loop).
                partial_.clear();
                if (!retry_) retry_ = std::make_unique<asio::steady_timer>(executor());
                retry_->expires_after(std::chrono::milliseconds(100));
                retry_->async_wait([this, self](boost::system::error_code e) {
                    if (!e && open_) read();
                });
                return;
            }
            finish(ec == asio::error::eof ? "end of file (the other side closed the link)" : ec.message());
            return;
        }
        hung_up_ = false;
        if (!present_ && n > 0) {
            present_ = true;
            if (on_presence) on_presence(true);
        }
        if (on_bytes) on_bytes(n);
        const std::uint64_t base = bytes_read_;
        bytes_read_ += n;
        std::size_t begin = 0;
        for (std::size_t i = 0; i < n; ++i) {
            if (buffer_[i] != '\n') continue;
            if (!overlong_) partial_.append(buffer_.data() + begin, i - begin);  // the tail of a cut line is dropped
            if (partial_.size() > max_line) partial_.resize(max_line), overlong_ = true;
            begin = i + 1;
            if (!overlong_ && !partial_.empty() && partial_.back() == '\r') partial_.pop_back();
            cut_ = overlong_;
            overlong_ = false;
            line_end_ = base + i + 1;
            std::string line;
            line.swap(partial_);
            on_line_(line);
            cut_ = false;
            if (!open_) return;  // the handler closed the link
        }
        if (!overlong_) {
            partial_.append(buffer_.data() + begin, n - begin);
            if (partial_.size() > max_line) partial_.resize(max_line), overlong_ = true;
        }
        read();
    });
}

void Link::send(std::string_view text) {
    if (!open_) return;
    out_ += text;
    write();
}

void Link::write() {
    if (writing_now_ || out_.empty() || !open_) return;
    writing_now_ = true;
    writing_.swap(out_);
    auto self = shared_from_this();
    write_all(asio::buffer(writing_), [this, self](boost::system::error_code ec, std::size_t n) {
        writing_now_ = false;
        bytes_written_ += n;
        writing_.clear();
        if (!open_) return;
        if (ec) {
            if (transient(ec)) {
                out_.clear();  // nobody is there to read it
                return;
            }
            finish(ec.message());
            return;
        }
        write();
    });
}

void Link::close() {
    if (!open_) return;
    open_ = false;
    if (retry_) retry_->cancel();
    close_stream();
}

void Link::finish(const std::string& why) {
    if (!open_) return;
    open_ = false;
    if (retry_) retry_->cancel();
    close_stream();
    if (on_close_) on_close_(why);
}

}  // namespace xlate5

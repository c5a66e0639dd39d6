// SPDX-License-Identifier: GPL-3.0-or-later
// The one idiom for asynchronous handlers in the service (timers, reads, posted work): a handler
// that may run after its object is gone is wrapped with guard(), which checks a weak reference
// to the object's lifetime token before calling in. No handler holds a bare `this` unchecked.
// (A Link additionally keeps itself alive while a read or write is pending: Asio reads into its
// buffer until the handler runs. The virtual printer, a test double owned by a shared_ptr,
// checks a weak_ptr to itself, which is the same check.)
#pragma once
#include <memory>
#include <utility>

namespace xlate5 {

class Lifetime {
public:
    Lifetime() = default;
    Lifetime(const Lifetime&) = delete;
    Lifetime& operator=(const Lifetime&) = delete;

    // f(args...) if the owner still exists when the handler runs; nothing otherwise.
    template <class F>
    auto guard(F f) const {
        return [alive = std::weak_ptr<const char>(token_), f = std::move(f)](auto&&... args) mutable {
            if (alive.lock()) f(std::forward<decltype(args)>(args)...);
        };
    }

private:
    std::shared_ptr<const char> token_ = std::make_shared<const char>(0);
};

}  // namespace xlate5

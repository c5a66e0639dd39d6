// SPDX-License-Identifier: GPL-3.0-or-later
#include "translators/suggest.hpp"

#include <algorithm>

namespace xlate5 {

std::string nearest_name(const std::string& typed, const std::vector<std::string>& known) {
    // Optimal string alignment distance: insertions, deletions, substitutions, adjacent swaps.
    const auto distance = [](const std::string& a, const std::string& b) {
        std::vector<std::vector<std::size_t>> d(a.size() + 1, std::vector<std::size_t>(b.size() + 1));
        for (std::size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
        for (std::size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
        for (std::size_t i = 1; i <= a.size(); ++i)
            for (std::size_t j = 1; j <= b.size(); ++j) {
                const std::size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
                d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
                if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
            }
        return d[a.size()][b.size()];
    };
    std::string best;
    std::size_t best_distance = 0;
    for (const auto& k : known) {
        const std::size_t dist = distance(typed, k);
        const std::size_t letters = std::max(typed.size(), k.size()) - (k.rfind("--", 0) == 0 ? 2 : k.rfind('-', 0) == 0 ? 1 : 0);
        if (dist == 0 || dist > std::max<std::size_t>(1, letters / 3)) continue;
        if (best.empty() || dist < best_distance) best = k, best_distance = dist;
    }
    return best;
}

}  // namespace xlate5

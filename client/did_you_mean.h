#pragma once
// "Did you mean" for pf's command line: the known name closest to a mistyped one by edit
// distance, so `pf rendr` and `pf render --photon 10` name what was probably meant.

#include <CLI/CLI.hpp>

#include <optional>
#include <string>
#include <vector>

namespace pf {

// Levenshtein distance (insert, delete, substitute; each costs 1).
int EditDistance(const std::string& a, const std::string& b);

// The name in `known` closest to `word`, if close enough to be a typo: at most a third of the
// word's length (at least 1, at most 3) edits away. Ties go to the first in `known`.
std::optional<std::string> ClosestName(const std::string& word, const std::vector<std::string>& known);

// One "did you mean" line per unrecognised token left over after `app` failed to parse: a
// subcommand name when none was recognised, else a long option of the chosen subcommand (or of
// `app`). Empty when nothing is close.
std::vector<std::string> DidYouMean(const CLI::App& app);

}  // namespace pf

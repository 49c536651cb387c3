#include "client/did_you_mean.h"

#include <algorithm>
#include <numeric>

namespace pf {

int EditDistance(const std::string& a, const std::string& b) {
  // One row of the dynamic-programming table at a time.
  std::vector<int> row(b.size() + 1);
  std::iota(row.begin(), row.end(), 0);
  for (size_t i = 1; i <= a.size(); ++i) {
    int diagonal = row[0];
    row[0] = int(i);
    for (size_t j = 1; j <= b.size(); ++j) {
      const int above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

std::optional<std::string> ClosestName(const std::string& word, const std::vector<std::string>& known) {
  const int limit = std::clamp(int(word.size()) / 3, 1, 3);
  std::optional<std::string> best;
  int best_distance = limit + 1;
  for (const std::string& name : known) {
    const int d = EditDistance(word, name);
    if (d < best_distance) {
      best_distance = d;
      best = name;
    }
  }
  return best;
}

namespace {

std::vector<std::string> LongOptionNames(const CLI::App& app) {
  std::vector<std::string> names;
  for (const CLI::Option* opt : app.get_options())
    for (const std::string& name : opt->get_lnames()) names.push_back("--" + name);
  return names;
}

}  // namespace

std::vector<std::string> DidYouMean(const CLI::App& app) {
  const std::vector<CLI::App*> chosen = app.get_subcommands();
  std::vector<std::string> subcommands;
  for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; }))
    subcommands.push_back(sub->get_name());
  std::vector<std::string> options = LongOptionNames(app);
  if (!chosen.empty()) {
    const std::vector<std::string> more = LongOptionNames(*chosen.front());
    options.insert(options.end(), more.begin(), more.end());
  }
  std::vector<std::string> hints;
  for (const std::string& token : app.remaining(true)) {
    const bool is_option = token.rfind("--", 0) == 0;
    if (!is_option && !chosen.empty()) continue;  // a stray value, not a name
    const std::string word = is_option ? token.substr(0, token.find('=')) : token;
    if (auto match = ClosestName(word, is_option ? options : subcommands); match && *match != word)
      hints.push_back("'" + word + "': did you mean '" + *match + "'?");
  }
  return hints;
}

}  // namespace pf

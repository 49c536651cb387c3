// MGF tokenizer and file reading (mgf_tokenizer.h); the spec is mgfdoc.tr.

#include "common/scene/mgf_tokenizer.h"

#include <algorithm>
#include <fstream>
#include <system_error>

namespace pf::mgf {
namespace {

namespace fs = std::filesystem;

constexpr uintmax_t kMaxFileBytes = uintmax_t{1} << 30;

bool IsBlank(char c) {
  return c == ' ' || c == '\t' || c == '\f' || c == '\v';
}

}  // namespace

void Tokenize(MgfFile& file) {
  const std::string& s = file.text;
  const size_t n = s.size();
  size_t pos = 0;
  int line = 1;
  auto eol_length = [&](size_t p) -> size_t {
    if (p >= n) return 0;
    if (s[p] == '\n') return 1;
    if (s[p] == '\r') return (p + 1 < n && s[p + 1] == '\n') ? 2 : 1;
    return 0;
  };
  while (pos < n) {
    const int entity_line = line;
    const size_t first_word = file.words.size();
    size_t word_start = std::string::npos;
    auto end_word = [&](size_t end) {
      if (word_start != std::string::npos) {
        file.words.emplace_back(s.data() + word_start, end - word_start);
        word_start = std::string::npos;
      }
    };
    while (pos < n) {
      const char c = s[pos];
      if (const size_t eol = eol_length(pos)) {
        end_word(pos);
        pos += eol;
        ++line;
        break;
      }
      if (c == '\\' && (pos + 1 == n || eol_length(pos + 1) > 0)) {
        end_word(pos);
        const size_t eol = eol_length(pos + 1);
        pos += 1 + eol;
        if (eol > 0) ++line;
        continue;
      }
      if (IsBlank(c)) {
        end_word(pos);
      } else if (word_start == std::string::npos) {
        word_start = pos;
      }
      ++pos;
    }
    end_word(pos);
    const size_t count = file.words.size() - first_word;
    if (count == 0) continue;
    if (file.words[first_word][0] == '#') {
      file.words.resize(first_word);
      continue;
    }
    file.entities.push_back(
        Entity{entity_line, static_cast<uint32_t>(first_word), static_cast<uint32_t>(count)});
  }
  // The last line that exists: a final end-of-line does not start another one.
  const bool ends_with_eol = n > 0 && (s[n - 1] == '\n' || s[n - 1] == '\r');
  file.last_line = std::max(1, ends_with_eol ? line - 1 : line);
}

std::string Quote(std::string_view w) {
  std::string r = "'";
  const size_t n = std::min<size_t>(w.size(), 40);
  for (size_t i = 0; i < n; ++i) {
    const unsigned char c = static_cast<unsigned char>(w[i]);
    r += (c >= 0x20 && c < 0x7f) ? static_cast<char>(c) : '?';
  }
  if (w.size() > n) r += "...";
  return r + "'";
}

std::string ReadWholeFile(const fs::path& path, std::string* out) {
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (ec || !fs::exists(st)) return "file not found";
  if (!fs::is_regular_file(st)) return "not a regular file";
  const uintmax_t size = fs::file_size(path, ec);
  if (ec) return "cannot determine the file size";
  if (size > kMaxFileBytes) return "file larger than 1 GiB";
  std::ifstream in(path, std::ios::binary);
  if (!in) return "cannot open the file";
  out->assign(static_cast<size_t>(size), '\0');
  if (size > 0 && !in.read(out->data(), static_cast<std::streamsize>(size))) {
    return "cannot read the file";
  }
  return {};
}

std::string CanonicalKey(const fs::path& p) {
  std::error_code ec;
  fs::path c = fs::weakly_canonical(p, ec);
  if (ec) {
    c = fs::absolute(p, ec);
    if (ec) c = p;
    c = c.lexically_normal();
  }
  return c.string();
}

}  // namespace pf::mgf

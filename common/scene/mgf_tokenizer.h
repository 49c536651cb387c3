#pragma once
// MGF files as the interpreter sees them (mgfdoc.tr §1, spec.txt "Other Details"): a file is read
// once into memory and cut into entities, the words of one logical line with continuation lines
// joined. Also the loader's file reading and the quoting of words in messages.

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace pf::mgf {

// Files: read once, cut into entities.

struct Entity {
  int line;        // physical line where the entity starts
  uint32_t first;  // index of its keyword in MgfFile::words
  uint32_t count;  // number of words, keyword included
};

struct MgfFile {
  std::string name;           // as shown in messages
  std::filesystem::path dir;  // base directory of its includes
  std::string canonical;      // identity for the include stack and the cache
  std::string text;
  std::vector<std::string_view> words;  // views into `text`
  std::vector<Entity> entities;
  int last_line = 1;
};

// §1 / spec.txt "Other Details": end of line is LF, CR or CRLF; a backslash right before the end
// of line continues the entity on the next line; blanks separate words. Comment entities are
// dropped here (first word starting with '#', see mgf_loader.h). Fills file.words, file.entities
// and file.last_line from file.text.
void Tokenize(MgfFile& file);

// Text of a word for messages: bounded length, no control characters (fuzzed input).
std::string Quote(std::string_view w);

// Reads a file for the loader; returns an error reason instead of throwing. Files larger than
// 1 GiB are refused.
std::string ReadWholeFile(const std::filesystem::path& path, std::string* out);

// Identity of a file for the include stack and the cache: its canonical path if it exists,
// else its normalised absolute path.
std::string CanonicalKey(const std::filesystem::path& p);

}  // namespace pf::mgf

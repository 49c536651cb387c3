// MGF tokenizer (common/scene/mgf_tokenizer.h, mgfdoc.tr §1 / spec.txt "Other Details"): LF, CR
// and CRLF line ends, backslash continuation, blanks, comments, the line each entity starts
// on, and the quoting of words in messages.

#include "common/scene/mgf_tokenizer.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace pf::mgf {
namespace {

struct Parsed {
  std::vector<std::vector<std::string>> entities;
  std::vector<int> lines;
  int last_line;
};

Parsed Parse(std::string text) {
  MgfFile f;
  f.text = std::move(text);
  Tokenize(f);
  Parsed p;
  for (const Entity& e : f.entities) {
    std::vector<std::string> words;
    for (uint32_t i = 0; i < e.count; ++i) words.emplace_back(f.words[e.first + i]);
    p.entities.push_back(std::move(words));
    p.lines.push_back(e.line);
  }
  p.last_line = f.last_line;
  return p;
}

TEST(MgfTokenizer, LineEndsContinuationsBlanksAndComments) {
  const Parsed p = Parse(
      "v a =\r\n"         // 1: CRLF
      "\tp 1\v 2\f 3\r"   // 2: CR, every blank kind
      "# comment line\n"  // 3: dropped
      "#f v1 v2 v4\n"     // 4: dropped (no blank after '#')
      "\n"                // 5: empty
      "f a b \\\n"        // 6: continued ...
      "  c d\\\r\n"       // 7: ... twice (CRLF after the backslash)
      "e\n"               // 8: end of the entity begun on line 6
      "sph a 1");         // 9: no final line end
  ASSERT_EQ(p.entities.size(), 4u);
  EXPECT_EQ(p.entities[0], (std::vector<std::string>{"v", "a", "="}));
  EXPECT_EQ(p.entities[1], (std::vector<std::string>{"p", "1", "2", "3"}));
  EXPECT_EQ(p.entities[2], (std::vector<std::string>{"f", "a", "b", "c", "d", "e"}));
  EXPECT_EQ(p.entities[3], (std::vector<std::string>{"sph", "a", "1"}));
  EXPECT_EQ(p.lines, (std::vector<int>{1, 2, 6, 9}));
  EXPECT_EQ(p.last_line, 9);
  // A final line end does not start another line; an empty file has line 1.
  EXPECT_EQ(Parse("o x\no\n").last_line, 2);
  EXPECT_EQ(Parse("").last_line, 1);
  EXPECT_TRUE(Parse(" \t\n\\\n").entities.empty());
}

TEST(MgfTokenizer, QuoteBoundsLengthAndHidesControlCharacters) {
  EXPECT_EQ(Quote("abc"), "'abc'");
  EXPECT_EQ(Quote(std::string("a\0b\x1b\x7f", 5)), "'a?b?\?'");
  EXPECT_EQ(Quote(std::string(41, 'x')), "'" + std::string(40, 'x') + "...'");
  EXPECT_EQ(Quote(std::string(40, 'x')), "'" + std::string(40, 'x') + "'");
}

}  // namespace
}  // namespace pf::mgf

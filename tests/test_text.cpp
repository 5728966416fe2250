// text::format: printf into a std::string, whole however long (the journal's lines, serve's
// records, identification's messages).
#include <gtest/gtest.h>

#include <string>

#include "pneu/config/text.hpp"

namespace pneu {
namespace {

TEST(TextFormat, PrintsWhatPrintfWouldPrint) {
  EXPECT_EQ(text::format("FAULT at %.3f s (y = %.3f mm): %s", 1.5, -12.25, "comms"),
            "FAULT at 1.500 s (y = -12.250 mm): comms");
  EXPECT_EQ(text::format("%s", ""), "");
}

TEST(TextFormat, KeepsALongTextWholeWhereAFixedBufferWouldCutIt) {
  const std::string path(2000, 'x');  // a path in a message: no buffer size bounds it
  const std::string line = text::format("cannot write %s: %s", path.c_str(), "No space left on device");
  EXPECT_EQ(line, "cannot write " + path + ": No space left on device");
  EXPECT_EQ(line.size(), 13 + 2000 + 25u);
}

}  // namespace
}  // namespace pneu

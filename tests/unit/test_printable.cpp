// flexopt::printable (core/error.hpp): messages that quote a file's text stay fit for a terminal.
#include "flexopt/core/error.hpp"

#include <gtest/gtest.h>

TEST(Printable, KeepsUtf8AndReplacesInvalidBytesAndControls) {
  // Valid UTF-8 of 2, 3 and 4 bytes, newline and tab stay as they are.
  const std::string good = "density \xcf\x81 \xe2\x89\xa5 0.5 \xf0\x9f\x94\xa7\n\tnext";
  EXPECT_EQ(flexopt::printable(good), good);
  // A lone continuation byte, a truncated 3-byte sequence, an overlong 2-byte lead, ESC and DEL.
  EXPECT_EQ(flexopt::printable("a\x80"
                               "b"),
            "a?b");
  EXPECT_EQ(flexopt::printable("c\xe2\x89"), "c??");
  EXPECT_EQ(flexopt::printable("\xc0\xaf"), "??");
  EXPECT_EQ(flexopt::printable("x\x1b[31my\x7f"), "x?[31my?");
}

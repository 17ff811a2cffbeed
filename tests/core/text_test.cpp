#include <gtest/gtest.h>

#include <string>
#include <voxwall/core/text.hpp>

using voxwall::formatLine;
using voxwall::humanBytes;

TEST(Text, HumanBytesPicksTheBinaryUnit) {
  EXPECT_EQ(humanBytes(0), "0 B");
  EXPECT_EQ(humanBytes(512), "512 B");
  EXPECT_EQ(humanBytes(1023), "1023 B");
  EXPECT_EQ(humanBytes(1024), "1.0 KiB");
  EXPECT_EQ(humanBytes(7.7 * 1024 * 1024), "7.7 MiB");
  EXPECT_EQ(humanBytes(3.0 * 1024 * 1024 * 1024), "3.0 GiB");
  EXPECT_EQ(humanBytes(2048.0 * 1024 * 1024 * 1024 * 1024), "2048.0 TiB");  // no unit past TiB
}

TEST(Text, DurationTextSaysWholeSecondsAsSeconds) {
  EXPECT_EQ(voxwall::durationText(300), "300 ms");
  EXPECT_EQ(voxwall::durationText(5000), "5 s");
  EXPECT_EQ(voxwall::durationText(1500), "1500 ms");
}

TEST(Text, FormatLineFormatsAndCutsLongLines) {
  EXPECT_EQ(formatLine("\n  %d atoms, %.2f dB", 64, 41.256), "\n  64 atoms, 41.26 dB");
  const std::string longText(600, 'x');
  const std::string line = formatLine("%s", longText.c_str());
  EXPECT_EQ(line.size(), 511u);
  EXPECT_EQ(line, longText.substr(0, 511));
}

// Outside text reaches a log only quoted: no newline, ESC or NUL can forge or cut a line.
TEST(Text, QuotedForLogEscapesEveryByteThatCouldForgeALine) {
  using voxwall::quotedForLog;
  EXPECT_EQ(quotedForLog("rotate 1 2"), "\"rotate 1 2\"");
  EXPECT_EQ(quotedForLog("a\nframe 9 presented\x1b[2J"), "\"a\\x0aframe 9 presented\\x1b[2J\"");
  EXPECT_EQ(quotedForLog(std::string("a\0b", 3)), "\"a\\x00b\"");
  EXPECT_EQ(quotedForLog("say \"hi\" \\ \xc3\xa9"), "\"say \\\"hi\\\" \\\\ \\xc3\\xa9\"");
  EXPECT_EQ(quotedForLog(std::string(100, 'x'), 8), "\"xxxxxxxx\"... (100 bytes)");
}

// HMAC-SHA256 against the RFC 4231 test vectors, hex round trips and the
// constant-time comparison.
#include "frictiond/crypto/hmac.h"

#include <string>

#include <gtest/gtest.h>

namespace frictiond {
namespace {

std::string Hex(const std::string& hex) {
  const auto b = FromHex(hex);
  EXPECT_TRUE(b.has_value()) << hex;
  return b.value_or("");
}

struct Rfc4231Case {
  const char* name;
  std::string key;
  std::string data;
  const char* mac_hex;  // full HMAC-SHA-256, or its first 128 bits (case 5)
};

TEST(HmacSha256, Rfc4231Vectors) {
  const std::string big_key(131, '\xaa');
  const Rfc4231Case cases[] = {
      {"1",
       std::string(20, '\x0b'),
       "Hi There",
       "b0344c61d8db38535ca8afceaf0bf12b881dc200c9833da726e9376c2e32cff7"},
      {"2",
       "Jefe",
       "what do ya want for nothing?",
       "5bdcc146bf60754e6a042426089575c75a003f089d2739839dec58b964ec3843"},
      {"3",
       std::string(20, '\xaa'),
       std::string(50, '\xdd'),
       "773ea91e36800e46854db8ebd09181a72959098b3ef8c122d9635514ced565fe"},
      {"4",
       Hex("0102030405060708090a0b0c0d0e0f10111213141516171819"),
       std::string(50, '\xcd'),
       "82558a389a443c0ea4cc819899f2083a85f0faa3e578f8077a2e3ff46729665b"},
      {"5 (truncated to 128 bits)",
       std::string(20, '\x0c'),
       "Test With Truncation",
       "a3b6167473100ee06e0c796c2955552b"},
      {"6",
       big_key,
       "Test Using Larger Than Block-Size Key - Hash Key First",
       "60e431591ee0b67f0d8a26aacbf5b77f8e0bc6213728c5140546040f0ee37f54"},
      {"7",
       big_key,
       "This is a test using a larger than block-size key and a larger than "
       "block-size data. The key needs to be hashed before being used by the "
       "HMAC algorithm.",
       "9b09ffa71b942fcb27635fbcd5b0e944bfdc63644f0713938a7f51535c3a35e2"},
  };
  for (const Rfc4231Case& c : cases) {
    const std::string mac = HmacSha256(c.key, c.data);
    ASSERT_EQ(mac.size(), 32u) << "case " << c.name;
    const std::string want = c.mac_hex;
    EXPECT_EQ(ToHex(mac).substr(0, want.size()), want) << "case " << c.name;
  }
}

TEST(HmacSha256, KeyAndDataChangeTheMac) {
  const std::string a = HmacSha256("key", "message");
  EXPECT_NE(a, HmacSha256("kez", "message"));
  EXPECT_NE(a, HmacSha256("key", "messagf"));
  EXPECT_EQ(a, HmacSha256("key", "message"));
  EXPECT_EQ(HmacSha256("", "").size(), 32u);  // empty key and data are valid
}

TEST(Hex, RoundTripAndRejection) {
  const std::string bytes("\x00\x01\xab\xff", 4);
  EXPECT_EQ(ToHex(bytes), "0001abff");
  EXPECT_EQ(FromHex("0001ABff"), bytes);
  EXPECT_FALSE(FromHex("abc"));  // odd length
  EXPECT_FALSE(FromHex("zz"));   // not hex
  EXPECT_FALSE(FromHex("0g"));
  EXPECT_EQ(FromHex(""), std::string());
}

TEST(ConstantTimeEqual, ComparesWholeStrings) {
  EXPECT_TRUE(ConstantTimeEqual("abc", "abc"));
  EXPECT_FALSE(ConstantTimeEqual("abc", "abd"));
  EXPECT_FALSE(ConstantTimeEqual("abc", "ab"));
  EXPECT_TRUE(ConstantTimeEqual("", ""));
}

TEST(RandomBytes, LengthAndVariety) {
  const std::string a = RandomBytes(16), b = RandomBytes(16);
  EXPECT_EQ(a.size(), 16u);
  EXPECT_NE(a, b);  // 2^-128 chance of a false failure
}

}  // namespace
}  // namespace frictiond

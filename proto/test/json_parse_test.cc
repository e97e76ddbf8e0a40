// The depth-bounded parser every outside JSON goes through (json_parse.h).
#include "frictiond/proto/json_parse.h"

#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

namespace frictiond {
namespace {

std::string Nested(int depth) {
  return std::string(static_cast<std::size_t>(depth), '[') +
         std::string(static_cast<std::size_t>(depth), ']');
}

TEST(ParseJson, AcceptsUpToTheDepthAndRefusesDeeper) {
  EXPECT_TRUE(ParseJson(Nested(kMaxJsonDepth), "body").is_array());
  EXPECT_TRUE(
      ParseJson(R"({"a": {"b": [1, 2, {"c": null}]}})", "body").is_object());
  // 100,000 levels: parsing alone is iterative, but copying or dumping
  // such a document recursed through the stack (a crash seen in the
  // daemon and the CLI); it is refused before anything touches it.
  for (int depth : {kMaxJsonDepth + 1, 100000, 300000}) {
    try {
      ParseJson(Nested(depth), "body");
      ADD_FAILURE() << depth << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()), "body: nesting deeper than 64");
    }
  }
  try {
    ParseJson("{\"a\": ", "--config x.json");
    ADD_FAILURE() << "accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).rfind("--config x.json: invalid JSON", 0),
              0u)
        << e.what();
  }
  EXPECT_TRUE(ParseJson("[[[1]]]", "body", 3).is_array());
  EXPECT_THROW(ParseJson("[[[[1]]]]", "body", 3), std::invalid_argument);
}

TEST(ParseJson, OrDiscardedNeverThrows) {
  EXPECT_TRUE(ParseJsonOrDiscarded(Nested(100000)).is_discarded());
  EXPECT_TRUE(ParseJsonOrDiscarded("not json").is_discarded());
  EXPECT_TRUE(ParseJsonOrDiscarded("").is_discarded());
  EXPECT_EQ(ParseJsonOrDiscarded(R"({"x": 1})")["x"], 1);
}

}  // namespace
}  // namespace frictiond

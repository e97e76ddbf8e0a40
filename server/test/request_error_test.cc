// The one rule that reads the field out of a validator's message
// (FieldNamedIn), on the message shapes the validators actually write, and
// the canonical codes' HTTP mapping.
#include "frictiond/server/request_error.h"

#include <gtest/gtest.h>

namespace frictiond {
namespace {

TEST(FieldNamedIn, ReadsTheFieldEachValidatorPutsFirst) {
  // Option checks: "field = value (rule)".
  EXPECT_EQ(FieldNamedIn("max_chunks = 0 (must be >= 1)"), "max_chunks");
  // Reassembler and parsers: "field: why".
  EXPECT_EQ(FieldNamedIn("n_samples: the stroke would exceed 100000 samples"),
            "n_samples");
  EXPECT_EQ(FieldNamedIn("entries[3].position: missing"),
            "entries[3].position");
  EXPECT_EQ(FieldNamedIn("joints[1].stiffness = -1 (must be > 0)"),
            "joints[1].stiffness");
  // A position first: the field after it.
  EXPECT_EQ(FieldNamedIn("line 3: mu = 2 (must be in [0, 1.5])"), "mu");
  EXPECT_EQ(FieldNamedIn("sample 7: fn_n = -1 (must be > 0)"), "fn_n");
}

TEST(FieldNamedIn, OddMessagesGiveTheirFirstWord) {
  EXPECT_EQ(FieldNamedIn(""), "");
  EXPECT_EQ(FieldNamedIn("oops"), "oops");
  EXPECT_EQ(FieldNamedIn("line 3"), "line");  // no ": " after the position
  EXPECT_EQ(FieldNamedIn("line 3: "), "");
}

TEST(StatusCodes, MapToOneHttpStatusEach) {
  EXPECT_EQ(HttpStatusFor(StatusCode::kInvalidArgument), 400);
  EXPECT_EQ(HttpStatusFor(StatusCode::kNotFound), 404);
  EXPECT_EQ(HttpStatusFor(StatusCode::kResourceExhausted), 413);
  EXPECT_EQ(HttpStatusFor(StatusCode::kFailedPrecondition), 422);
  EXPECT_EQ(HttpStatusFor(StatusCode::kUnavailable), 503);
  EXPECT_STREQ(StatusCodeName(StatusCode::kInvalidArgument),
               "invalid_argument");
}

}  // namespace
}  // namespace frictiond

// MemoKeyBuilder: equal inputs give equal keys, and a change anywhere in a
// column (a flipped last bit, two words swapped, the length) changes the
// key, through the serial words and the four-lane bulk path alike.
#include "frictiond/estimators/identification_memo.h"

#include <cstdint>
#include <cstring>
#include <random>
#include <set>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

namespace frictiond {
namespace {

MemoKey KeyOf(const std::vector<double>& x, std::size_t b, std::size_t e) {
  MemoKeyBuilder h(42);
  h.Add(x, b, e);
  return h.Key();
}

double FlipLastBit(double d) {
  std::uint64_t u;
  std::memcpy(&u, &d, sizeof u);
  u ^= 1;
  std::memcpy(&d, &u, sizeof d);
  return d;
}

TEST(MemoKeyBuilder, EqualColumnsEqualKeysAndEveryChangeShows) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::set<std::pair<std::uint64_t, std::uint64_t>> seen;
  int keys = 0;
  for (std::size_t n : {0u, 1u, 3u, 4u, 7u, 8u, 9u, 13u, 64u, 250u, 1001u}) {
    std::vector<double> x(n + 3);
    for (double& v : x) v = u(rng);
    const MemoKey k = KeyOf(x, 2, 2 + n);
    EXPECT_EQ(k, KeyOf(std::vector<double>(x), 2, 2 + n)) << n;
    seen.insert({k.a, k.b});
    ++keys;
    for (std::size_t i = 0; i < n; ++i) {
      std::vector<double> y = x;
      y[2 + i] = FlipLastBit(y[2 + i]);
      const MemoKey ky = KeyOf(y, 2, 2 + n);
      EXPECT_FALSE(ky == k) << "n " << n << " flipped " << i;
      seen.insert({ky.a, ky.b});
      ++keys;
      if (i + 1 < n && x[2 + i] != x[3 + i]) {
        std::vector<double> z = x;
        std::swap(z[2 + i], z[3 + i]);
        EXPECT_FALSE(KeyOf(z, 2, 2 + n) == k) << "n " << n << " swapped " << i;
      }
    }
    // The range, not the vector: a neighbour outside it changes nothing.
    std::vector<double> w = x;
    w[0] = FlipLastBit(w[0]);
    w[n + 2] = FlipLastBit(w[n + 2]);
    EXPECT_EQ(KeyOf(w, 2, 2 + n), k) << n;
  }
  // A zero appended is another column (the length is part of the key).
  EXPECT_FALSE(KeyOf({1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0}, 0, 8) ==
               KeyOf({1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 0.0}, 0, 9));
  EXPECT_EQ(seen.size(), static_cast<std::size_t>(keys));
}

}  // namespace
}  // namespace frictiond

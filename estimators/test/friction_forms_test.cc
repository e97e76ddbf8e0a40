#include "frictiond/estimators/friction_forms.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

namespace frictiond {
namespace {

struct Samples {
  std::vector<double> fn, mu;
  std::vector<int> stroke;
};

// 20 strokes x 200 samples, Fn uniform in [0.5, 4.5], mu = truth(Fn) +
// N(0, noise) + a per-stroke offset N(0, offset_sd).
template <typename F>
Samples Simulate(F truth,
                 std::uint64_t seed,
                 double noise = 0.02,
                 double offset_sd = 0.0) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> fn_u(0.5, 4.5);
  std::normal_distribution<double> e(0.0, noise), off(0.0, offset_sd);
  Samples s;
  for (int k = 0; k < 20; ++k) {
    const double o = offset_sd > 0 ? off(rng) : 0.0;
    for (int i = 0; i < 200; ++i) {
      const double fn = fn_u(rng);
      s.fn.push_back(fn);
      s.mu.push_back(truth(fn) + o + e(rng));
      s.stroke.push_back(k);
    }
  }
  return s;
}

const FormFit& Get(const FormComparison& c, FrictionForm f) {
  for (const FormFit& x : c.forms)
    if (x.form == f) return x;
  throw std::logic_error("missing form");
}

bool SameFamily(FrictionForm a, FrictionForm b) {
  auto recip = [](FrictionForm f) {
    return f == FrictionForm::kReciprocal || f == FrictionForm::kThirion;
  };
  return a == b || (recip(a) && recip(b));
}

std::string Table(const FormComparison& c) {
  std::string t;
  for (const FormFit& f : c.forms) {
    t += std::string(ToString(f.form)) + ": a " + std::to_string(f.a) + " b " +
         std::to_string(f.b) + " r2 " + std::to_string(f.r2) + " cv_mae " +
         std::to_string(f.cv_mae) + "\n";
  }
  return t;
}

TEST(FrictionForms, DataFromEachFormIsBestFitByThatForm) {
  struct Case {
    FrictionForm form;
    double a, b;
  };
  const Case cases[] = {{FrictionForm::kLinear, -0.08, 1.0},
                        {FrictionForm::kReciprocal, 0.35, 0.6},
                        {FrictionForm::kInverseCube, 0.05, 0.7},
                        {FrictionForm::kSchallamach, 1.0, 0.0},
                        {FrictionForm::kThirion, 0.6, 0.35}};
  std::uint64_t seed = 100;
  for (const Case& k : cases) {
    const Samples s = Simulate(
        [&](double fn) { return EvalFrictionForm(k.form, k.a, k.b, fn); },
        ++seed);
    const FormComparison c = CompareFrictionForms(s.fn, s.mu, s.stroke);
    ASSERT_TRUE(c.valid) << c.why;
    EXPECT_EQ(c.folds, 5);
    EXPECT_TRUE(SameFamily(c.best, k.form))
        << "truth " << ToString(k.form) << ", best " << ToString(c.best)
        << " (seed " << seed << ")\n"
        << Table(c);
    const FormFit& own = Get(c, k.form);
    ASSERT_TRUE(own.valid) << own.why;
    EXPECT_NEAR(own.a, k.a, 0.05 * std::fabs(k.a)) << ToString(k.form);
    if (k.b != 0) {
      EXPECT_NEAR(own.b, k.b, 0.05 * std::fabs(k.b));
    }
    // Held-out error of the true form is about the noise's MAE
    // (0.02 * sqrt(2/pi) = 0.016) and Coulomb's is larger.
    EXPECT_NEAR(own.cv_mae, 0.016, 0.002) << ToString(k.form);
    EXPECT_GT(Get(c, FrictionForm::kCoulomb).cv_mae, 1.5 * own.cv_mae);
  }
}

TEST(FrictionForms, NullCaseConstantMuIsNotBeatenMuch) {
  // Nothing planted: no form improves on Coulomb's constant by more than
  // noise.
  const Samples s = Simulate([](double) { return 0.8; }, 7);
  const FormComparison c = CompareFrictionForms(s.fn, s.mu, s.stroke);
  ASSERT_TRUE(c.valid) << c.why;
  const double coulomb = Get(c, FrictionForm::kCoulomb).cv_mae;
  for (const FormFit& f : c.forms) {
    if (f.form == FrictionForm::kSchallamach) {
      EXPECT_GT(f.cv_mae, 1.5 * coulomb) << Table(c);  // no intercept
      continue;
    }
    EXPECT_GT(f.cv_mae, 0.99 * coulomb) << Table(c);
  }
}

TEST(FrictionForms, OneStrokeCannotBeComparedAndSizesAreChecked) {
  const FormComparison c =
      CompareFrictionForms({1, 2, 3, 4}, {0.9, 0.8, 0.7, 0.6}, {0, 0, 0, 0});
  EXPECT_FALSE(c.valid);
  EXPECT_NE(c.why.find("stroke"), std::string::npos);
  EXPECT_NEAR(Get(c, FrictionForm::kLinear).a, -0.1, 1e-12);
  EXPECT_THROW(CompareFrictionForms({1}, {0.9, 0.8}, {0}),
               std::invalid_argument);
  EXPECT_THROW(CompareFrictionForms({1}, {0.9}, {0}, 1), std::invalid_argument);
}

TEST(FrictionForms, ConstantLoadIdentifiesOnlyOneParameterForms) {
  // Like data/microtribo_recip: Fn = 5 N +- 0.005.
  std::vector<double> fn, mu;
  std::vector<int> stroke;
  for (int i = 0; i < 400; ++i) {
    fn.push_back(5.0 + 0.005 * std::sin(0.37 * i));
    mu.push_back(0.35 + 0.05 * std::sin(1.3 * i));
    stroke.push_back(i / 40);
  }
  const FormComparison c = CompareFrictionForms(fn, mu, stroke);
  ASSERT_TRUE(c.valid) << c.why;
  EXPECT_FALSE(Get(c, FrictionForm::kLinear).valid);
  EXPECT_NE(Get(c, FrictionForm::kLinear).why.find("no span"),
            std::string::npos);
  EXPECT_FALSE(Get(c, FrictionForm::kThirion).valid);
  EXPECT_TRUE(Get(c, FrictionForm::kCoulomb).valid);
  EXPECT_TRUE(Get(c, FrictionForm::kSchallamach).valid);
}

}  // namespace
}  // namespace frictiond

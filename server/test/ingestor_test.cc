#include "frictiond/server/ingestor.h"

#include <atomic>
#include <condition_variable>
#include <mutex>
#include <numeric>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "frictiond/estimators/slip_likelihood.h"
#include "frictiond/estimators/stochastic_model.h"
#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/proto/slip_likelihood_json.h"
#include "frictiond/server/library.h"
#include "frictiond/testing/daemon_process.h"
#include "frictiond/testing/stroke_simulator.h"

namespace frictiond {
namespace {

using nlohmann::json;

/// `strokes` simulated strokes of 300 samples each (eq. (1) truth).
std::string SimulatedCsv(std::uint64_t seed, int strokes = 2) {
  testing::SimulationSpec spec;
  spec.strokes = strokes;
  return FormatStrokeCsv(testing::SimulateStrokes(spec, seed));
}

std::size_t Samples(const std::string& csv) {
  return ParseStrokeCsv(csv).size();
}

/// eq. (1) refitted from the store alone (no cache), as IngestStrokes did
/// before the ingestor: the truth the cached path must reproduce.
StochasticFrictionModel RefitFromStore(FrictionLibrary& lib,
                                       const std::string& material,
                                       const SlipLabelOptions& labelling) {
  StochasticFitOptions o;
  o.labelling = labelling;
  const StochasticFit fit =
      FitStochasticModel(lib.LoadStrokes(material, "default", labelling), o);
  EXPECT_TRUE(fit.status == FitStatus::kOk || fit.status == FitStatus::kPartial)
      << fit.why;
  return fit.model;
}

void ExpectSameFit(const StochasticFrictionModel& a,
                   const StochasticFrictionModel& b) {
  EXPECT_EQ(a.samples_total, b.samples_total);
  EXPECT_EQ(a.samples_slip, b.samples_slip);
  ASSERT_EQ(a.mu.beta.size(), b.mu.beta.size());
  for (Eigen::Index i = 0; i < a.mu.beta.size(); ++i)
    EXPECT_DOUBLE_EQ(a.mu.beta[i], b.mu.beta[i]) << i;
  EXPECT_DOUBLE_EQ(a.mu.sigma_eps, b.mu.sigma_eps);
}

TEST(SelectFitUploadsTest, TakesAllBelowTheCap) {
  const std::vector<std::size_t> sizes = {100, 200, 300};
  const FitChoice all = SelectFitUploads(sizes, 600);
  EXPECT_EQ(all.indices, (std::vector<std::size_t>{0, 1, 2}));
  EXPECT_EQ(all.stride, 1u);
  EXPECT_TRUE(SelectFitUploads({}, 0).indices.empty());
  // An upload above the cap alone is left out; the rest still fit.
  EXPECT_EQ(SelectFitUploads({5000, 100, 100, 9000}, 1000).indices,
            (std::vector<std::size_t>{1, 2}));
}

TEST(SelectFitUploadsTest, AboveTheCapNestedStridesWithinTheCap) {
  const std::vector<std::size_t> sizes(1000, 250);
  const FitChoice c = SelectFitUploads(sizes, 6000);
  // Stride 32 would take 32 uploads (8,000 samples); 64 takes 16 (4,000).
  EXPECT_EQ(c.stride, 64u);
  ASSERT_EQ(c.indices.size(), 16u);
  for (std::size_t k = 0; k < c.indices.size(); ++k)
    EXPECT_EQ(c.indices[k], 64 * k);  // old and recent uploads represented
  EXPECT_EQ(SelectFitUploads(sizes, 6000).indices, c.indices);  // deterministic
}

TEST(SelectFitUploadsTest, ConsecutiveChoicesShareTheirUploads) {
  // What lets the cache drop uploads off the stride: appending uploads
  // never brings back one that a choice left out, and the stride never
  // shrinks. Uneven sizes, including some above the cap.
  for (std::size_t cap : {1000u, 5000u, 20000u}) {
    std::vector<std::size_t> sizes;
    FitChoice previous;
    for (int n = 1; n <= 600; ++n) {
      sizes.push_back(n % 97 == 0 ? 2 * cap : 50 + (n * 7919) % 900);
      const FitChoice c = SelectFitUploads(sizes, cap);
      ASSERT_GE(c.stride, 1u) << n;  // no fallback: upload 0 fits
      EXPECT_GE(c.stride, previous.stride) << cap << " " << n;
      for (std::size_t i : c.indices) {
        EXPECT_EQ(i % c.stride, 0u);
        if (i + 1 < sizes.size()) {  // an older upload: chosen before
          EXPECT_TRUE(std::binary_search(
              previous.indices.begin(), previous.indices.end(), i))
              << cap << " " << n << " " << i;
        }
      }
      previous = c;
    }
  }
}

TEST(SelectFitUploadsTest, UnevenSizesStayWithinTheCap) {
  std::vector<std::size_t> sizes;
  for (int i = 0; i < 300; ++i) sizes.push_back(50 + (i * 7919) % 900);
  for (std::size_t cap : {1000u, 5000u, 20000u}) {
    std::size_t sum = 0;
    const auto chosen = SelectFitUploads(sizes, cap).indices;
    ASSERT_FALSE(chosen.empty());
    for (std::size_t i : chosen) sum += sizes[i];
    EXPECT_LE(sum, cap) << cap;
    EXPECT_GT(sum, cap / 4) << cap;  // not far below it either
  }
}

TEST(SelectFitUploadsTest, NoneFitsTakesTheNewestWhole) {
  EXPECT_EQ(SelectFitUploads({5000, 9000, 7000}, 1000).indices,
            (std::vector<std::size_t>{2}));
  EXPECT_EQ(SelectFitUploads({5000, 9000, 7000}, 1000).stride, 0u);
  EXPECT_EQ(SelectFitUploads({500, 9000, 7000}, 1000).indices,
            (std::vector<std::size_t>{0}));
}

class IngestorTest : public ::testing::Test {
 protected:
  IngestorTest() : dir_("ingestor_test") {}
  std::string Url() const { return dir_.path() + "/lib.db"; }
  std::unique_ptr<FrictionLibrary> Open(std::size_t fit_cap = 6000) {
    LibraryOptions o;
    o.ingest.fit_sample_cap = fit_cap;
    return std::make_unique<FrictionLibrary>(OpenStore(Url()), o);
  }
  testing::TempDir dir_;
};

TEST_F(IngestorTest, CachedRefitEqualsARefitFromTheStore) {
  auto lib = Open(/*fit_cap=*/1'000'000);
  std::size_t total = 0;
  IngestResult r;
  for (int i = 0; i < 5; ++i) {
    const std::string csv = SimulatedCsv(10 + i);
    total += Samples(csv);
    r = lib->IngestStrokes("felt", csv, {});
    EXPECT_EQ(r.version, i + 1);
  }
  EXPECT_EQ(r.model->set.stochastic->samples_total, static_cast<int>(total));
  ExpectSameFit(*r.model->set.stochastic,
                RefitFromStore(*lib, "felt", SlipLabelOptions{}));
  // Eq. (2), whose Newton steps started from the previous refit's fit
  // (Ingestor::PairLock::conditional_start), equals a cold fit of the
  // stored strokes to the steps' tolerance.
  {
    const StrokeData d =
        lib->LoadStrokes("felt", "default", SlipLabelOptions{});
    std::vector<double> ratio(d.size());
    for (std::size_t i = 0; i < d.size(); ++i) ratio[i] = d.ft_n[i] / d.fn_n[i];
    const ConditionalSlipLikelihood cold =
        FitConditionalSlipLikelihood(d.fn_n, ratio, d.slip);
    const ConditionalSlipLikelihood served = ConditionalSlipFromJson(
        r.model->set.other.at(kConditionalSlipFamilyKey));
    ASSERT_TRUE(cold.valid) << cold.why;
    ASSERT_EQ(served.knot_fn_n, cold.knot_fn_n);
    for (std::size_t k = 0; k < cold.knot_c1.size(); ++k) {
      EXPECT_NEAR(served.knot_c1[k], cold.knot_c1[k], 1e-7 * cold.knot_c1[k]);
      EXPECT_NEAR(served.knot_c2[k], cold.knot_c2[k], 1e-7);
    }
  }
  // The returned model is the committed version, as a store read gives it.
  EXPECT_EQ(r.model->json_text,
            lib->FindModelVersion("felt", "default", r.version)->json_text);
  EXPECT_EQ(lib->FindModel("felt", "default"), r.model);  // cached as is
}

TEST_F(IngestorTest, ALabellingChangeRelabelsTheHistory) {
  auto lib = Open(1'000'000);
  lib->IngestStrokes("felt", SimulatedCsv(20), {});
  lib->IngestStrokes("felt", SimulatedCsv(21), {});
  IngestOptions o;
  SlipLabelOptions l;
  l.peak_mm_s = 25.0;
  l.floor_mm_s = 12.0;
  o.labelling = l;
  const IngestResult r = lib->IngestStrokes("felt", SimulatedCsv(22), o);
  ExpectSameFit(*r.model->set.stochastic, RefitFromStore(*lib, "felt", l));
}

TEST_F(IngestorTest, ARejectedUploadStoresNothingAndKeepsTheCache) {
  auto lib = Open(1'000'000);
  lib->IngestStrokes("felt", SimulatedCsv(30), {});
  lib->IngestStrokes("felt", SimulatedCsv(31), {});
  const std::string no_slip =
      "t_s,fn_n,ft_n,v_mm_s\n0,1,0.2,0\n0.01,1,0.3,0\n0.02,1,0.4,0.5\n";
  // A 422 (no slip on a fresh pair) ...
  EXPECT_THROW(lib->IngestStrokes("glass", no_slip, {}), RequestError);
  EXPECT_FALSE(lib->store().GetMaterial("glass"));
  // ... and a bad CSV on the pair with history.
  EXPECT_THROW(
      lib->IngestStrokes("felt", "t_s,fn_n,ft_n,v_mm_s\n0,-1,1,0\n", {}),
      RequestError);
  EXPECT_EQ(lib->store().ListStrokes("felt", "default").size(), 2u);
  const IngestResult r = lib->IngestStrokes("felt", SimulatedCsv(32), {});
  EXPECT_EQ(r.version, 3);
  ExpectSameFit(*r.model->set.stochastic,
                RefitFromStore(*lib, "felt", SlipLabelOptions{}));
}

TEST_F(IngestorTest, ARejectedFitOnAPairWithHistoryKeepsTheCache) {
  auto lib = Open(1'000'000);
  // A family fitter that throws makes the whole fit fail after the cache
  // was used: nothing is stored and the next upload still sees the history.
  std::atomic<bool> fail{false};
  lib->AddFamilyFitter("probe",
                       [&fail](const StrokeData&,
                               const StrokeData&,
                               const CachedModel*,
                               std::string*) -> json {
                         if (fail) throw std::runtime_error("probe failed");
                         return nullptr;
                       });
  lib->IngestStrokes("felt", SimulatedCsv(33), {});
  fail = true;
  EXPECT_ANY_THROW(lib->IngestStrokes("felt", SimulatedCsv(34), {}));
  fail = false;
  EXPECT_EQ(lib->store().ListStrokes("felt", "default").size(), 1u);
  const IngestResult r = lib->IngestStrokes("felt", SimulatedCsv(35), {});
  EXPECT_EQ(r.version, 2);
  ExpectSameFit(*r.model->set.stochastic,
                RefitFromStore(*lib, "felt", SlipLabelOptions{}));
}

TEST_F(IngestorTest, DeleteAndInvalidationDropTheCache) {
  auto a = Open(1'000'000);
  auto b = Open(1'000'000);  // a second daemon on the same database
  a->IngestStrokes("felt", SimulatedCsv(40), {});
  // b's stroke reaches a's cache by the catch-up query, without a notice.
  b->IngestStrokes("felt", SimulatedCsv(41), {});
  const std::string third = SimulatedCsv(42);
  IngestResult r = a->IngestStrokes("felt", third, {});
  EXPECT_EQ(r.version, 3);
  ExpectSameFit(*r.model->set.stochastic,
                RefitFromStore(*a, "felt", SlipLabelOptions{}));
  // b deletes the material; a hears of it (fleet notice) and starts over.
  EXPECT_TRUE(b->DeleteMaterial("felt"));
  a->InvalidateCached("felt", "default");
  const std::string fresh = SimulatedCsv(43);
  r = a->IngestStrokes("felt", fresh, {});
  EXPECT_EQ(r.version, 1);
  EXPECT_EQ(r.model->set.stochastic->samples_total,
            static_cast<int>(Samples(fresh)));
  // A delete through this library needs no notice.
  EXPECT_TRUE(a->DeleteMaterial("felt"));
  r = a->IngestStrokes("felt", fresh, {});
  EXPECT_EQ(r.version, 1);
  EXPECT_EQ(r.model->set.stochastic->samples_total,
            static_cast<int>(Samples(fresh)));
}

TEST_F(IngestorTest, AboveTheCapTheRefitIsBoundedAndSaysSo) {
  auto lib = Open(/*fit_cap=*/1500);  // 2.5 uploads of 600 samples
  std::vector<std::size_t> sizes;
  IngestResult r;
  for (int i = 0; i < 8; ++i) {
    const std::string csv = SimulatedCsv(50 + i);
    sizes.push_back(Samples(csv));
    r = lib->IngestStrokes("felt", csv, {});
  }
  // The last refit got the stratified choice of the 7 older uploads + it.
  sizes.pop_back();
  std::size_t expected = Samples(SimulatedCsv(57));
  for (std::size_t i : SelectFitUploads(sizes, 1500).indices)
    expected += sizes[i];
  EXPECT_EQ(r.model->set.stochastic->samples_total, static_cast<int>(expected));
  EXPECT_LE(expected, 1500u + Samples(SimulatedCsv(57)));
  EXPECT_NE(r.fit_note.find("bounded refit:"), std::string::npos) << r.fit_note;
  EXPECT_NE(r.fit_note.find("of 7 stored uploads"), std::string::npos)
      << r.fit_note;
}

/// Blocks the family fitter of uploads that carry a `hold` column until
/// released: an upload of one pair held inside its fit.
struct Gate {
  std::mutex mu;
  std::condition_variable cv;
  bool entered = false;
  bool released = false;
};

TEST_F(IngestorTest, PairsProceedInParallelAndVersionsFollowUploadOrder) {
  auto lib = Open();
  auto gate = std::make_shared<Gate>();
  lib->AddFamilyFitter("gate",
                       [gate](const StrokeData&,
                              const StrokeData& upload,
                              const CachedModel*,
                              std::string*) -> json {
                         if (!upload.FindCovariate("hold")) return nullptr;
                         std::unique_lock<std::mutex> lock(gate->mu);
                         gate->entered = true;
                         gate->cv.notify_all();
                         gate->cv.wait(lock, [&] { return gate->released; });
                         return nullptr;
                       });
  testing::SimulationSpec spec;
  spec.strokes = 2;
  spec.covariates.push_back({"hold", [](int, double, double) { return 1.0; }});
  const std::string held_csv =
      FormatStrokeCsv(testing::SimulateStrokes(spec, 60));
  std::thread held([&] { lib->IngestStrokes("felt", held_csv, {}); });
  {
    std::unique_lock<std::mutex> lock(gate->mu);
    gate->cv.wait(lock, [&] { return gate->entered; });
  }
  // felt's upload is inside its fit, holding felt's lock: other pairs
  // (another material, another fingertip) and reads are not blocked.
  EXPECT_EQ(lib->IngestStrokes("cork", SimulatedCsv(61), {}).version, 1);
  IngestOptions tip_b;
  tip_b.fingertip = "tip-b";
  EXPECT_EQ(lib->IngestStrokes("felt", SimulatedCsv(62), tip_b).version, 1);
  EXPECT_FALSE(lib->FindModel("felt", "default"));
  {
    std::lock_guard<std::mutex> lock(gate->mu);
    gate->released = true;
  }
  gate->cv.notify_all();
  held.join();
  EXPECT_EQ(lib->FindModel("felt", "default")->set.version, 1);

  // Two clients per pair on two pairs: each pair's versions are 1..n, each
  // client sees its versions increase, and a version's stroke is the upload
  // that made it (versions follow upload order).
  constexpr int kPerClient = 4;
  std::vector<std::string> csvs;
  for (int i = 0; i < 4 * kPerClient; ++i) csvs.push_back(SimulatedCsv(70 + i));
  std::vector<std::vector<IngestResult>> results(4);
  std::vector<std::thread> clients;
  for (int c = 0; c < 4; ++c) {
    clients.emplace_back([&, c] {
      const std::string material = c < 2 ? "ash" : "oak";
      for (int i = 0; i < kPerClient; ++i)
        results[c].push_back(
            lib->IngestStrokes(material, csvs[c * kPerClient + i], {}));
    });
  }
  for (auto& t : clients) t.join();
  for (const std::string material : {"ash", "oak"}) {
    const int first = material == std::string("ash") ? 0 : 2;
    std::vector<int> versions;
    for (int c = first; c < first + 2; ++c) {
      for (int i = 0; i < kPerClient; ++i) {
        const IngestResult& r = results[c][i];
        versions.push_back(r.version);
        if (i > 0) {
          EXPECT_GT(r.version, results[c][i - 1].version);
        }
        EXPECT_EQ(
            lib->store().GetModel(material, "default", r.version)->stroke_id,
            r.stroke_id);
      }
    }
    std::sort(versions.begin(), versions.end());
    std::vector<int> want(2 * kPerClient);
    std::iota(want.begin(), want.end(), 1);
    EXPECT_EQ(versions, want) << material;
    // Stroke ids increase with the version: upload order within the pair.
    const auto models = lib->store().ListModels(material, "default");
    for (std::size_t v = 1; v < models.size(); ++v)
      EXPECT_GT(models[v].stroke_id, models[v - 1].stroke_id);
    // The newest model was fitted on every upload of the pair.
    std::size_t total = 0;
    for (int c = first; c < first + 2; ++c)
      for (int i = 0; i < kPerClient; ++i)
        total += Samples(csvs[c * kPerClient + i]);
    EXPECT_EQ(
        lib->FindModel(material, "default")->set.stochastic->samples_total,
        static_cast<int>(total));  // below the cap: all of them
  }
}

TEST_F(IngestorTest, CacheStaysWithinItsSampleCap) {
  LibraryOptions o;
  o.ingest.cache_sample_cap = 1000;  // below two pairs' history
  FrictionLibrary lib(OpenStore(":memory:"), o);
  lib.IngestStrokes("felt", SimulatedCsv(80), {});
  lib.IngestStrokes("felt", SimulatedCsv(81), {});
  lib.IngestStrokes("cork", SimulatedCsv(82), {});
  // felt (least recently used) was shed; its next refit reads back the
  // uploads it chooses (here all: below the fit cap).
  const IngestResult r = lib.IngestStrokes("felt", SimulatedCsv(83), {});
  EXPECT_EQ(r.version, 3);
  EXPECT_EQ(
      r.model->set.stochastic->samples_total,
      static_cast<int>(Samples(SimulatedCsv(80)) + Samples(SimulatedCsv(81)) +
                       Samples(SimulatedCsv(83))));
}

TEST_F(IngestorTest, AShedPairReadsBackOnlyTheChosenUploads) {
  // 40 uploads; a fit cap that takes a stratified few; a cache cap that
  // sheds the pair whenever another pair is ingested. The refit after a
  // shed equals the refit of a pair that was never shed.
  LibraryOptions small;
  small.ingest.fit_sample_cap = 1500;
  small.ingest.cache_sample_cap = 500;
  LibraryOptions big = small;
  big.ingest.cache_sample_cap = 100'000'000;
  FrictionLibrary shed(OpenStore(":memory:"), small);
  FrictionLibrary kept(OpenStore(":memory:"), big);
  for (int k = 0; k < 40; ++k) {
    const std::string csv = SimulatedCsv(200 + k, 2);
    shed.IngestStrokes("felt", csv, {});
    kept.IngestStrokes("felt", csv, {});
    shed.IngestStrokes("cork", SimulatedCsv(500 + k, 2), {});  // sheds felt
  }
  const IngestResult a = shed.IngestStrokes("felt", SimulatedCsv(999, 2), {});
  const IngestResult b = kept.IngestStrokes("felt", SimulatedCsv(999, 2), {});
  EXPECT_EQ(a.version, 41);
  EXPECT_EQ(a.model->set.stochastic->samples_total,
            b.model->set.stochastic->samples_total);
  EXPECT_LT(a.model->set.stochastic->samples_total,
            40 * static_cast<int>(Samples(SimulatedCsv(200, 2))));
  const auto& beta_a = a.model->set.stochastic->mu.beta;
  const auto& beta_b = b.model->set.stochastic->mu.beta;
  ASSERT_EQ(beta_a.size(), beta_b.size());
  for (Eigen::Index i = 0; i < beta_a.size(); ++i)
    EXPECT_EQ(beta_a[i], beta_b[i]) << i;
}

TEST_F(IngestorTest, TwoBusyPairsAboveTheCacheCapReadNothingBack) {
  // Two pairs uploading in turn, their histories (2 x 40 x ~300 samples)
  // above the cache cap, their refits' choices (<= 3,000 + 300 each) below
  // it. Each pair keeps only the uploads its refits can still choose, so
  // no upload is read back from the store (before, each upload shed the
  // other pair and its next refit read its choice back: ~10 reads per
  // upload). The models equal those of a cache that never evicts.
  LibraryOptions small;
  small.ingest.fit_sample_cap = 3000;
  small.ingest.cache_sample_cap = 10'000;
  LibraryOptions big = small;
  big.ingest.cache_sample_cap = 100'000'000;
  FrictionLibrary lib(OpenStore(":memory:"), small);
  FrictionLibrary ref(OpenStore(":memory:"), big);
  for (int k = 0; k < 40; ++k) {
    for (const char* m : {"felt", "cork"}) {
      const std::string csv = SimulatedCsv(300 + 2 * k + (m[0] == 'c'), 1);
      const IngestResult a = lib.IngestStrokes(m, csv, {});
      const IngestResult b = ref.IngestStrokes(m, csv, {});
      ASSERT_EQ(a.model->set.stochastic->samples_total,
                b.model->set.stochastic->samples_total)
          << m << " " << k;
      EXPECT_EQ(a.model->set.stochastic->mu.beta,
                b.model->set.stochastic->mu.beta)
          << m << " " << k;
    }
    EXPECT_LE(lib.ingestor().cached_samples(), small.ingest.cache_sample_cap);
  }
  EXPECT_EQ(lib.ingestor().store_reads(), 0u);
  EXPECT_LT(ref.ingestor().cached_samples(), 2 * (3000u + 2 * 400u))
      << "each pair keeps about its refit's choice";
}

}  // namespace
}  // namespace frictiond

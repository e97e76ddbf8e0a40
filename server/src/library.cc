#include "frictiond/server/library.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <future>
#include <sstream>

#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/proto/actuator_json.h"
#include "frictiond/server/text.h"

namespace frictiond {

using nlohmann::json;

bool IsValidId(const std::string& id) {
  if (id.empty() || id.size() > 64 || id == "." || id == "..") return false;
  for (char c : id) {
    const bool ok = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') ||
                    (c >= '0' && c <= '9') || c == '.' || c == '_' || c == '-';
    if (!ok) return false;
  }
  return true;
}

void CheckId(const std::string& id, const std::string& field) {
  if (!IsValidId(id)) {
    std::string shown = id.substr(0, 80);
    for (char& c : shown) {
      if (static_cast<unsigned char>(c) < 0x20 ||
          static_cast<unsigned char>(c) >= 0x7f)
        c = '?';
    }
    throw RequestError(
        400,
        field,
        field + " = '" + shown +
            "' (must match [A-Za-z0-9._-]{1,64} and not be '.' or '..')");
  }
}

double ParseNumberParam(const std::string& name, const std::string& value) {
  double x = 0;
  const char* b = value.data();
  const char* e = value.data() + value.size();
  auto [p, ec] = std::from_chars(b, e, x);
  if (value.empty() || ec != std::errc() || p != e) {
    throw RequestError(
        400, name, name + " = '" + ShownText(value) + "' (not a number)");
  }
  if (!std::isfinite(x))
    throw RequestError(
        400, name, name + " = '" + ShownText(value) + "' (must be finite)");
  return x;
}

int ParseVersionParam(const std::string& value) {
  const double x = ParseNumberParam("version", value);
  if (!(x >= 1 && x == std::floor(x) && x < 1e9))
    throw RequestError(
        400,
        "version",
        "version = '" + ShownText(value) + "' (must be a positive integer)");
  return static_cast<int>(x);
}

std::optional<SlipLabelOptions> ParseLabelling(
    const std::function<std::optional<std::string>(const std::string&)>& get,
    const SlipLabelOptions& base) {
  SlipLabelOptions o = base;
  bool any = false;
  auto take = [&](const char* name, double* field) {
    if (auto v = get(name)) {
      *field = ParseNumberParam(name, *v);
      any = true;
    }
  };
  take("slip_peak_mm_s", &o.peak_mm_s);
  take("slip_floor_mm_s", &o.floor_mm_s);
  take("median_window_s", &o.median_window_s);
  take("max_fn_n", &o.max_fn_n);
  take("max_v_mm_s", &o.max_v_mm_s);
  if (!any) return std::nullopt;
  std::string why;
  if (!o.IsValid(&why))
    throw RequestError(400, why.substr(0, why.find(' ')), why);
  return o;
}

namespace {

std::string Key(const std::string& material, const std::string& fingertip) {
  return material + '\n' + fingertip;
}

}  // namespace

FrictionLibrary::FrictionLibrary(std::unique_ptr<Store> store,
                                 LibraryOptions options)
    : store_(std::move(store)), options_(options) {}

FrictionLibrary::~FrictionLibrary() {
  // The store's listener thread calls back into this object.
  if (watching_) store_->SetChangeListener(nullptr);
}

void FrictionLibrary::WatchStoreChanges() {
  watching_ = true;
  store_->SetChangeListener(
      [this](const std::string& material, const std::string& fingertip) {
        OnStoreChange(material, fingertip);
      });
}

void FrictionLibrary::ForgetAnnounced(const std::string& material) {
  // A deleted and re-created material starts again at version 1.
  std::lock_guard<std::mutex> lock(listeners_mu_);
  for (auto it = notified_.begin(); it != notified_.end();) {
    it = it->first.rfind(material + '\n', 0) == 0 ? notified_.erase(it)
                                                  : std::next(it);
  }
}

void FrictionLibrary::OnStoreChange(const std::string& material,
                                    const std::string& fingertip) {
  if (material.empty()) {
    InvalidateAllCached();
    return;
  }
  if (fingertip.empty()) {
    ForgetAnnounced(material);
    std::unique_lock lock(cache_mu_);
    ++cache_gen_;
    for (auto it = cache_.begin(); it != cache_.end();) {
      if (it->first.rfind(material + '\n', 0) == 0) {
        stale_[it->first] = it->second;
        it = cache_.erase(it);
      } else {
        ++it;
      }
    }
    return;
  }
  Invalidate(material, fingertip);
  bool announce;
  {
    std::lock_guard<std::mutex> lock(listeners_mu_);
    announce = !listeners_.empty();
  }
  if (announce) Notify(FindModel(material, fingertip));
}

std::vector<Material> FrictionLibrary::ListMaterials() {
  return store_->ListMaterials();
}

Material FrictionLibrary::GetMaterial(const std::string& id) {
  CheckId(id, "id");
  auto m = store_->GetMaterial(id);
  if (!m) throw RequestError(404, "id", "unknown material '" + id + "'");
  return *m;
}

bool FrictionLibrary::PutMaterial(const std::string& id,
                                  const std::string& json_body) {
  CheckId(id, "id");
  json body = json::object();
  if (!json_body.empty()) {
    try {
      body = json::parse(json_body);
    } catch (const json::exception& e) {
      throw RequestError(
          400, "body", std::string("body: invalid JSON: ") + e.what());
    }
  }
  if (!body.is_object())
    throw RequestError(
        400, "body", "body: expected a JSON object {name, description, tags}");
  Material m;
  m.id = id;
  if (auto old = store_->GetMaterial(id)) m = *old;
  for (auto it = body.begin(); it != body.end(); ++it) {
    const std::string& k = it.key();
    if (k == "name" || k == "description") {
      if (!it->is_string())
        throw RequestError(400, k, k + ": expected a string");
      const std::string s = it->get<std::string>();
      if (s.size() > (k == "name" ? 200u : 4000u)) {
        throw RequestError(400,
                           k,
                           k + ": " + std::to_string(s.size()) +
                               " characters (at most " +
                               (k == "name" ? "200" : "4000") + ")");
      }
      (k == "name" ? m.name : m.description) = s;
    } else if (k == "tags") {
      if (!it->is_array())
        throw RequestError(400, k, "tags: expected an array of strings");
      if (it->size() > 64)
        throw RequestError(
            400,
            k,
            "tags: " + std::to_string(it->size()) + " tags (at most 64)");
      std::vector<std::string> tags;
      for (const auto& t : *it) {
        if (!t.is_string())
          throw RequestError(400, k, "tags: expected an array of strings");
        if (t.get<std::string>().size() > 64)
          throw RequestError(400, k, "tags: a tag longer than 64 characters");
        tags.push_back(t.get<std::string>());
      }
      m.tags = tags;
    } else {
      throw RequestError(400,
                         k,
                         "body: unknown field '" + k.substr(0, 64) +
                             "' (allowed: name, description, tags)");
    }
  }
  if (m.name.empty()) m.name = id;
  return store_->PutMaterial(m);
}

bool FrictionLibrary::DeleteMaterial(const std::string& id) {
  CheckId(id, "id");
  const bool deleted = store_->DeleteMaterial(id);
  ForgetAnnounced(id);
  std::unique_lock lock(cache_mu_);
  ++cache_gen_;
  for (auto it = cache_.begin(); it != cache_.end();) {
    it = it->first.rfind(id + '\n', 0) == 0 ? cache_.erase(it) : std::next(it);
  }
  for (auto it = stale_.begin(); it != stale_.end();) {
    it = it->first.rfind(id + '\n', 0) == 0 ? stale_.erase(it) : std::next(it);
  }
  return deleted;
}

std::shared_ptr<const CachedModel> FrictionLibrary::Decode(
    const ModelRecord& r) const {
  auto cm = std::make_shared<CachedModel>();
  json j = json::parse(r.json);
  cm->set = ModelSetFromJson(j);
  cm->set.material = r.material;
  cm->set.fingertip = r.fingertip;
  cm->set.version = r.version;
  cm->set.created_at = r.created_at;
  json out = ModelSetToJson(cm->set);
  out["reason"] = r.reason;
  cm->json_text = out.dump();
  return cm;
}

std::shared_ptr<const CachedModel> FrictionLibrary::FindModel(
    const std::string& material, const std::string& fingertip) {
  const std::string key = Key(material, fingertip);
  std::uint64_t gen;
  {
    std::shared_lock lock(cache_mu_);
    auto it = cache_.find(key);
    if (it != cache_.end()) return it->second;
    gen = cache_gen_;
  }
  std::optional<ModelRecord> record;
  try {
    record = store_->GetLatestModel(material, fingertip);
  } catch (const StoreUnavailable&) {
    // Database server away: serve the last model this daemon knew.
    std::shared_lock lock(cache_mu_);
    auto it = stale_.find(key);
    if (it == stale_.end()) throw;
    return it->second;
  }
  if (!record) return nullptr;
  auto cm = Decode(*record);
  std::unique_lock lock(cache_mu_);
  stale_.erase(key);
  if (cache_gen_ != gen) return cm;  // invalidated meanwhile: do not cache
  auto [it, inserted] = cache_.emplace(key, cm);
  if (!inserted && it->second->set.version < cm->set.version) it->second = cm;
  return it->second;
}

std::shared_ptr<const CachedModel> FrictionLibrary::FindModelVersion(
    const std::string& material, const std::string& fingertip, int version) {
  auto record = store_->GetModel(material, fingertip, version);
  return record ? Decode(*record) : nullptr;
}

json FrictionLibrary::MakeStrokePlan(const std::string& material,
                                     const std::string& fingertip) const {
  const StrokePlanOptions& p = options_.plan;
  json plan =
      json{{"material", material},
           {"fingertip", fingertip},
           {"fn_n", {p.fn_min_n, p.fn_max_n}},
           {"v_mm_s", {p.v_min_mm_s, p.v_max_mm_s}},
           {"max_duration_s", p.max_duration_s},
           {"min_span_pct", p.min_span_pct},
           {"instructions",
            "slide the fingertip on the surface in repeated strokes with "
            "rests between them, sweeping normal "
            "force over fn_n and peak sliding speed over v_mm_s; then POST "
            "the samples as a stroke CSV (t_s, "
            "fn_n, ft_n, v_mm_s) to /v1/materials/" +
                material + "/strokes?fingertip=" + fingertip}};
  if (p.lugre_pair) {
    const double fn_n =
        p.lugre_fn_n > 0 ? p.lugre_fn_n : 0.5 * (p.fn_min_n + p.fn_max_n);
    plan["lugre"] = json{
        {"fn_n", fn_n},
        {"slow",
         {{"accel_mm_s2", p.lugre_slow_accel_mm_s2},
          {"peak_mm_s", p.lugre_slow_peak_mm_s}}},
        {"fast",
         {{"strokes", p.lugre_fast_strokes},
          {"accel_mm_s2", p.lugre_fast_accel_mm_s2},
          {"peak_mm_s", p.lugre_fast_peak_mm_s}}},
        {"rest_s", p.lugre_rest_s},
        {"instructions",
         "end the stroke with the LuGre identifying pair at normal force "
         "fn_n: a slow triangle 0 -> slow.peak_mm_s -> 0 at |dv/dt| = "
         "slow.accel_mm_s2, then fast.strokes triangles 0 -> fast.peak_mm_s "
         "-> 0 at fast.accel_mm_s2, with rest_s of rest between triangles "
         "(rest_s / 2 before the first and after the last)"}};
  }
  return plan;
}

json FrictionLibrary::RequestIdentification(const std::string& material,
                                            const std::string& fingertip,
                                            const std::string& requested_by) {
  CheckText(requested_by, "robot", 128);
  const json plan = MakeStrokePlan(material, fingertip);
  {
    // Reads must not grow the store without bound: an open job for the
    // pair is reused, and new ones stop at the caps (the store's listing
    // of open jobs is bounded by the same caps).
    std::lock_guard<std::mutex> lock(request_mu_);
    const int total_cap = std::max(options_.max_open_requests, 0);
    bool pair_open = false;
    int open_total = 0, open_mine = 0;
    for (const IdentificationJob& j :
         store_->ListJobsPage(/*open_only=*/true, 0, total_cap + 1)) {
      ++open_total;
      if (j.requested_by == requested_by) ++open_mine;
      if (j.material == material && j.fingertip == fingertip) pair_open = true;
    }
    std::string why;
    if (!pair_open && open_total >= total_cap) {
      why = std::to_string(open_total) +
            " identification requests are open (the daemon's cap); none was "
            "recorded";
    } else if (!pair_open &&
               open_mine >= options_.max_open_requests_per_requester) {
      why = "requester '" + ShownText(requested_by, 64) + "' has " +
            std::to_string(open_mine) +
            " open identification requests (the cap per requester); none "
            "was recorded";
    }
    if (!why.empty())
      return json{{"requested", false}, {"reason", why}, {"stroke", plan}};
  }
  IdentificationJob job;
  job.material = material;
  job.fingertip = fingertip;
  job.state = "requested";
  job.plan_json = plan.dump();
  job.requested_by = requested_by;
  job.detail = "waiting for a test stroke";
  const IdentificationJob j = store_->RequestIdentification(job);
  return json{{"requested", true},
              {"job_id", j.id},
              {"state", j.state},
              {"created_at", j.created_at},
              {"stroke", json::parse(j.plan_json)}};
}

std::shared_ptr<const CachedModel> FrictionLibrary::RequireModel(
    const std::string& material,
    const std::string& fingertip,
    const std::string& requested_by) {
  CheckId(material, "id");
  CheckId(fingertip, "fingertip");
  if (auto m = FindModel(material, fingertip)) return m;
  const bool known = store_->GetMaterial(material).has_value();
  json extra = json{{"material", material},
                    {"fingertip", fingertip},
                    {"known_material", known}};
  extra["identification"] =
      RequestIdentification(material, fingertip, requested_by);
  const std::string outcome =
      extra["identification"].value("requested", false)
          ? "an identification was requested"
          : "no identification was recorded (" +
                extra["identification"].value("reason", std::string()) + ")";
  throw RequestError(404,
                     "id",
                     known ? "material '" + material +
                                 "' has no friction model for fingertip '" +
                                 fingertip + "' yet: " + outcome
                           : "unknown material '" + material + "': " + outcome,
                     extra);
}

StrokeData FrictionLibrary::LoadStrokes(
    const std::string& material,
    const std::string& fingertip,
    std::optional<SlipLabelOptions> labelling) {
  if (!labelling) {
    auto model = FindModel(material, fingertip);
    labelling = model && model->set.stochastic
                    ? model->set.stochastic->labelling
                    : SlipLabelOptions{};
  }
  StrokeData all;
  for (const StrokeRecord& info : store_->ListStrokes(material, fingertip)) {
    auto s = store_->GetStroke(info.id);
    if (!s) continue;
    StrokeData d = ParseStrokeCsv(
        s->csv, StrokeCsvOptions{options_.max_samples_per_upload, 64});
    PrepareUpload(&d, *labelling);
    all.Append(d);
  }
  return all;
}

void FrictionLibrary::PrepareUpload(StrokeData* data,
                                    const SlipLabelOptions& labelling) {
  // Labels, strokes and derived features are per upload: time gaps,
  // dwell and distance restart with each upload.
  EnsureLabels(data, labelling);
  AddDerivedFeatures(data, labelling.gap_factor);
}

IngestResult FrictionLibrary::IngestStrokes(const std::string& material,
                                            const std::string& csv,
                                            const IngestOptions& options) {
  CheckId(material, "id");
  CheckId(options.fingertip, "fingertip");
  if (options.robot.size() > 128)
    throw RequestError(400, "robot", "robot: at most 128 characters");
  // 1. Validate the upload completely before touching the store.
  StrokeData upload;
  try {
    upload = ParseStrokeCsv(
        csv, StrokeCsvOptions{options_.max_samples_per_upload, 64});
  } catch (const StrokeCsvError& e) {
    const int status =
        e.field() == "body" && std::string(e.what()).find("samples (split") !=
                                   std::string::npos
            ? 413
            : 400;
    throw RequestError(status, e.field(), e.what(), json{{"line", e.line()}});
  }
  std::lock_guard<std::mutex> lock(ingest_mu_);
  // 2. Labelling: explicit, else the pair's previous one, else defaults.
  SlipLabelOptions labelling;
  auto previous = FindModel(material, options.fingertip);
  if (options.labelling) {
    labelling = *options.labelling;
  } else if (previous && previous->set.stochastic) {
    labelling = previous->set.stochastic->labelling;
  }
  // 3. Refit on all strokes of the pair plus this one.
  StrokeData all = LoadStrokes(material, options.fingertip, labelling);
  const std::size_t n_new = upload.size();
  PrepareUpload(&upload, labelling);
  if (all.empty()) {
    all = upload;  // first upload of the pair: no merge needed
  } else {
    all.Append(upload);
  }
  StochasticFitOptions fit_options;
  if (previous && previous->set.stochastic) {
    // Keep an extended model's terms (product columns included) and its eps
    // scale when they can be computed from the data.
    fit_options = CalcRefitOptions(*previous->set.stochastic, all);
  }
  fit_options.labelling = labelling;
  // The family fitters (LuGre, eq. (2), ...) read only the data: they run
  // on a second thread while eq. (1) is fitted (as IdentifyMaterial does).
  struct FamilyFit {
    std::string family;
    json model;
    std::string note;
  };
  std::future<std::vector<FamilyFit>> families =
      std::async(std::launch::async, [this, &all, &upload, &previous] {
        std::vector<FamilyFit> out;
        for (const auto& [family, fitter] : fitters_) {
          FamilyFit f{family, nullptr, ""};
          f.model = fitter(all, upload, previous.get(), &f.note);
          out.push_back(std::move(f));
        }
        return out;
      });
  StochasticFit fit = FitStochasticModel(all, fit_options);
  if (fit.status != FitStatus::kOk && fit.status != FitStatus::kPartial) {
    families.wait();  // it reads `all`
    throw RequestError(
        422,
        "v_mm_s",
        "stroke accepted as CSV but no model can be identified: " + fit.why,
        json{{"fit_status", ToString(fit.status)}});
  }
  // 4. One transaction: stroke + model version.
  ModelSet set;
  set.material = material;
  set.fingertip = options.fingertip;
  set.stochastic = fit.model;
  if (previous) {
    for (auto it = previous->set.other.begin(); it != previous->set.other.end();
         ++it) {
      if (it.key() != "reason") set.other[it.key()] = *it;
    }
  }
  std::string family_notes;
  for (FamilyFit& f : families.get()) {
    if (!f.model.is_null()) set.other[f.family] = std::move(f.model);
    if (!f.note.empty()) {
      family_notes +=
          (family_notes.empty() ? "" : "; ") + f.family + ": " + f.note;
    }
  }
  StrokeRecord stroke;
  stroke.material = material;
  stroke.fingertip = options.fingertip;
  stroke.robot = options.robot;
  stroke.samples = static_cast<std::int64_t>(n_new);
  stroke.csv = csv;
  ModelRecord record;
  record.material = material;
  record.fingertip = options.fingertip;
  record.reason = "upload";
  json doc = ModelSetToJson(set);
  doc.erase("version");
  doc.erase("created_at");
  record.json = doc.dump();
  const UploadCommit commit = store_->CommitUpload(stroke, record);
  Invalidate(material, options.fingertip);
  IngestResult out;
  out.stroke_id = commit.stroke_id;
  out.version = commit.version;
  out.material_created = commit.material_created;
  out.samples = n_new;
  out.model = FindModel(material, options.fingertip);
  out.fit_status = ToString(fit.status);
  out.fit_note = fit.why;
  if (!family_notes.empty())
    out.fit_note += (out.fit_note.empty() ? "" : "; ") + family_notes;
  Notify(out.model);
  return out;
}

std::shared_ptr<const CachedModel> FrictionLibrary::AddModelVersion(
    const std::string& material,
    const std::string& fingertip,
    const StochasticFrictionModel& model,
    const std::string& reason,
    const json& extra_families) {
  std::lock_guard<std::mutex> lock(ingest_mu_);
  ModelSet set;
  set.material = material;
  set.fingertip = fingertip;
  set.stochastic = model;
  if (auto previous = FindModel(material, fingertip))
    set.other = previous->set.other;
  for (auto it = extra_families.begin(); it != extra_families.end(); ++it)
    set.other[it.key()] = *it;
  ModelRecord record;
  record.material = material;
  record.fingertip = fingertip;
  record.reason = reason;
  json doc = ModelSetToJson(set);
  doc.erase("version");
  doc.erase("created_at");
  record.json = doc.dump();
  store_->AddModelVersion(record);
  Invalidate(material, fingertip);
  auto m = FindModel(material, fingertip);
  Notify(m);
  return m;
}

std::shared_ptr<const CachedModel> FrictionLibrary::AddFamilyVersion(
    const std::string& material,
    const std::string& fingertip,
    const std::string& family,
    const json& family_json,
    const std::string& reason) {
  std::lock_guard<std::mutex> lock(ingest_mu_);
  if (!store_->GetMaterial(material)) {
    Material m;
    m.id = material;
    m.name = material;
    store_->PutMaterial(m);
  }
  ModelSet set;
  set.material = material;
  set.fingertip = fingertip;
  if (auto previous = FindModel(material, fingertip)) {
    set.stochastic = previous->set.stochastic;
    set.other = previous->set.other;
  }
  set.other[family] = family_json;
  ModelRecord record;
  record.material = material;
  record.fingertip = fingertip;
  record.reason = reason;
  json doc = ModelSetToJson(set);
  doc.erase("version");
  doc.erase("created_at");
  record.json = doc.dump();
  store_->AddModelVersion(record);
  Invalidate(material, fingertip);
  auto m = FindModel(material, fingertip);
  Notify(m);
  return m;
}

void FrictionLibrary::Invalidate(const std::string& material,
                                 const std::string& fingertip) {
  std::unique_lock lock(cache_mu_);
  ++cache_gen_;
  const std::string key = Key(material, fingertip);
  auto it = cache_.find(key);
  if (it != cache_.end()) {
    stale_[key] = it->second;
    cache_.erase(it);
  }
}

void FrictionLibrary::InvalidateCached(const std::string& material,
                                       const std::string& fingertip) {
  Invalidate(material, fingertip);
}

void FrictionLibrary::InvalidateAllCached() {
  std::unique_lock lock(cache_mu_);
  ++cache_gen_;
  for (auto& [key, model] : cache_) stale_[key] = model;
  cache_.clear();
}

void FrictionLibrary::AddFamilyFitter(const std::string& family,
                                      FamilyFitter fitter) {
  fitters_.emplace_back(family, std::move(fitter));
}

void FrictionLibrary::AddModelListener(ModelListener listener) {
  std::lock_guard<std::mutex> lock(listeners_mu_);
  listeners_.push_back(std::move(listener));
}

void FrictionLibrary::Notify(const std::shared_ptr<const CachedModel>& model) {
  if (!model) return;
  std::vector<ModelListener> copy;
  {
    std::lock_guard<std::mutex> lock(listeners_mu_);
    // Once per version: a version made here and announced by the store's
    // change notification, or seen twice, is announced once.
    int& last = notified_[Key(model->set.material, model->set.fingertip)];
    if (model->set.version <= last) return;
    last = model->set.version;
    copy = listeners_;
  }
  for (auto& l : copy) l(*model);
}

int FrictionLibrary::LoadBundledData(const std::string& dir) {
  if (!store_->ListMaterials().empty()) return 0;
  const std::filesystem::path root(dir);
  const std::filesystem::path manifest = root / "datasets.json";
  std::ifstream in(manifest);
  if (!in)
    throw std::runtime_error("--data " + dir + ": no datasets.json manifest");
  json m;
  try {
    m = json::parse(in);
  } catch (const json::exception& e) {
    throw std::runtime_error(manifest.string() + ": invalid JSON: " + e.what());
  }
  int loaded = 0;
  for (const json& d : m.at("datasets")) {
    const std::string id = d.at("material").get<std::string>();
    const std::filesystem::path csv_path =
        root / d.at("csv").get<std::string>();
    std::ifstream f(csv_path, std::ios::binary);
    if (!f)
      throw std::runtime_error(manifest.string() + ": cannot read " +
                               csv_path.string());
    std::stringstream ss;
    ss << f.rdbuf();
    IngestOptions options;
    options.fingertip = d.value("fingertip", "default");
    options.robot = "bundled:" + d.at("csv").get<std::string>();
    SlipLabelOptions labelling;
    if (d.contains("labelling")) {
      const json& l = d["labelling"];
      labelling.peak_mm_s = l.value("slip_peak_mm_s", labelling.peak_mm_s);
      labelling.floor_mm_s = l.value("slip_floor_mm_s", labelling.floor_mm_s);
      labelling.median_window_s =
          l.value("median_window_s", labelling.median_window_s);
    }
    options.labelling = labelling;
    try {
      IngestStrokes(id, ss.str(), options);
    } catch (const RequestError& e) {
      throw std::runtime_error(csv_path.string() + ": " + e.what());
    }
    json body = {{"name", d.value("name", id)},
                 {"description", d.value("description", "")},
                 {"tags", d.value("tags", std::vector<std::string>{})}};
    PutMaterial(id, body.dump());
    ++loaded;
  }
  // Actuator log sets (issue 20, docs/actuator.md): the bundled identified
  // model of a robot joint becomes the "actuator" family of (robot, joint),
  // with the logs it was fitted on checked (parsed and replayed) here.
  if (m.contains("actuator_datasets")) {
    for (const json& d : m.at("actuator_datasets")) {
      const std::string robot = d.at("robot").get<std::string>();
      const std::string joint = d.value("joint", "default");
      const std::filesystem::path model_path =
          root / d.at("model").get<std::string>();
      std::ifstream mf(model_path);
      if (!mf)
        throw std::runtime_error(manifest.string() + ": cannot read " +
                                 model_path.string());
      json family;
      ActuatorModel model;
      try {
        family = json::parse(mf);
        model = ActuatorModelFromJson(family.at("model"));
      } catch (const std::exception& e) {
        throw std::runtime_error(model_path.string() + ": " + e.what());
      }
      json logs = json::array();
      for (const json& l : d.at("logs")) {
        const std::filesystem::path lp = root / l.get<std::string>();
        std::ifstream lf(lp, std::ios::binary);
        std::stringstream ls;
        ls << lf.rdbuf();
        try {
          const ActuatorLog log =
              ParseActuatorLog(ls.str(), lp.stem().string());
          logs.push_back({{"name", log.name},
                          {"kp", log.kp},
                          {"trajectory", log.trajectory},
                          {"samples", log.size()},
                          {"mae_rad", SimulateActuatorLog(model, log)}});
        } catch (const std::invalid_argument& e) {
          throw std::runtime_error(lp.string() + ": " + e.what());
        }
      }
      family["logs"] = logs;
      family["source"] = d.value("name", robot);
      AddFamilyVersion(robot, joint, "actuator", family, "bundled");
      json body = {{"name", d.value("name", robot)},
                   {"description", d.value("description", "")},
                   {"tags", d.value("tags", std::vector<std::string>{})}};
      PutMaterial(robot, body.dump());
      ++loaded;
    }
  }
  return loaded;
}

}  // namespace frictiond

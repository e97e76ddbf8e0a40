#include "frictiond/server/library.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <future>
#include <sstream>
#include <thread>

#include "frictiond/estimators/field_error.h"
#include "frictiond/estimators/identification.h"
#include "frictiond/estimators/stroke_csv.h"
#include "frictiond/proto/actuator_json.h"
#include "frictiond/proto/json_parse.h"
#include "frictiond/proto/lugre_json.h"
#include "frictiond/proto/slip_likelihood_json.h"
#include "frictiond/server/identification_json.h"
#include "frictiond/server/model_lookup.h"
#include "frictiond/server/text.h"

namespace frictiond {

using nlohmann::json;

const char* StatusCodeName(StatusCode code) {
  switch (code) {
    case StatusCode::kInvalidArgument:
      return "invalid_argument";
    case StatusCode::kUnauthenticated:
      return "unauthenticated";
    case StatusCode::kPermissionDenied:
      return "permission_denied";
    case StatusCode::kNotFound:
      return "not_found";
    case StatusCode::kAlreadyExists:
      return "already_exists";
    case StatusCode::kResourceExhausted:
      return "resource_exhausted";
    case StatusCode::kFailedPrecondition:
      return "failed_precondition";
    case StatusCode::kUnavailable:
      return "unavailable";
    case StatusCode::kUnimplemented:
      return "unimplemented";
    case StatusCode::kInternal:
      break;
  }
  return "internal";
}

int HttpStatusFor(StatusCode code) {
  switch (code) {
    case StatusCode::kInvalidArgument:
      return 400;
    case StatusCode::kUnauthenticated:
      return 401;
    case StatusCode::kPermissionDenied:
      return 403;
    case StatusCode::kNotFound:
      return 404;
    case StatusCode::kAlreadyExists:
      return 409;
    case StatusCode::kResourceExhausted:
      return 413;
    case StatusCode::kFailedPrecondition:
      return 422;
    case StatusCode::kUnavailable:
      return 503;
    case StatusCode::kUnimplemented:
      return 501;
    case StatusCode::kInternal:
      break;
  }
  return 500;
}

RequestError InvalidArgumentFrom(const std::invalid_argument& e,
                                 const std::string& fallback_field,
                                 const std::string& prefix) {
  const auto* typed = dynamic_cast<const FieldError*>(&e);
  const FieldError named = typed != nullptr && !typed->field().empty()
                               ? *typed
                               : FieldError(fallback_field, e.what());
  const FieldError outer = named.Prefixed(prefix);  // the one prefix rule
  return RequestError(
      StatusCode::kInvalidArgument, outer.field(), outer.what());
}

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
        StatusCode::kInvalidArgument,
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
    throw RequestError(StatusCode::kInvalidArgument,
                       name,
                       name + " = '" + ShownText(value) + "' (not a number)");
  }
  if (!std::isfinite(x))
    throw RequestError(StatusCode::kInvalidArgument,
                       name,
                       name + " = '" + ShownText(value) + "' (must be finite)");
  return x;
}

int ParseVersionParam(const std::string& value) {
  const double x = ParseNumberParam("version", value);
  if (!(x >= 1 && x == std::floor(x) && x < 1e9))
    throw RequestError(
        StatusCode::kInvalidArgument,
        "version",
        "version = '" + ShownText(value) + "' (must be a positive integer)");
  return static_cast<int>(x);
}

nlohmann::json ParseJsonBody(const std::string& body) {
  try {
    return ParseJson(body, "body");
  } catch (const std::invalid_argument& e) {
    throw RequestError(StatusCode::kInvalidArgument, "body", e.what());
  }
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
    throw RequestError(
        StatusCode::kInvalidArgument, why.substr(0, why.find(' ')), why);
  return o;
}

namespace {

std::string Key(const std::string& material, const std::string& fingertip) {
  return material + '\n' + fingertip;
}

// A bundled manifest entry's name, description and tags.
MaterialUpdate BundledMaterial(const json& entry, const std::string& id) {
  MaterialUpdate m;
  m.name = entry.value("name", id);
  m.description = entry.value("description", "");
  m.tags = entry.value("tags", std::vector<std::string>{});
  return m;
}

}  // namespace

FrictionLibrary::FrictionLibrary(std::unique_ptr<Store> store,
                                 LibraryOptions options)
    : store_(std::move(store)), options_(options) {
  options_.ingest.max_samples_per_upload = options_.max_samples_per_upload;
  ingestor_ = std::make_unique<Ingestor>(*store_, options_.ingest);
  // One per hardware thread: at most that many second shares can run at
  // once anyway; one waiting in the queue is run by its own upload. A refit
  // splits only while a core is free for its share (FitWorkers::Begin).
  fit_workers_ = std::make_unique<FitWorkers>(
      static_cast<int>(std::max(1u, std::thread::hardware_concurrency())));
}

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
  ingestor_->Invalidate(material, fingertip);
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
  if (!m)
    throw RequestError(
        StatusCode::kNotFound, "id", "unknown material '" + id + "'");
  return *m;
}

bool FrictionLibrary::PutMaterial(const std::string& id,
                                  const MaterialUpdate& update) {
  CheckId(id, "id");
  constexpr std::size_t kMaxName = 200, kMaxDescription = 4000;
  constexpr std::size_t kMaxTags = 64, kMaxTag = 64;
  auto too_long =
      [](const std::string& field, std::size_t size, std::size_t max) {
        return RequestError(StatusCode::kInvalidArgument,
                            field,
                            field + ": " + std::to_string(size) +
                                " characters (at most " + std::to_string(max) +
                                ")");
      };
  if (update.name) {
    if (update.name->size() > kMaxName)
      throw too_long("name", update.name->size(), kMaxName);
    CheckText(*update.name, "name", kMaxName);
  }
  if (update.description) {
    if (update.description->size() > kMaxDescription)
      throw too_long(
          "description", update.description->size(), kMaxDescription);
    // Free text: line breaks allowed, other control characters not.
    CheckFreeText(*update.description, "description", kMaxDescription);
  }
  if (update.tags) {
    if (update.tags->size() > kMaxTags)
      throw RequestError(StatusCode::kInvalidArgument,
                         "tags",
                         "tags: " + std::to_string(update.tags->size()) +
                             " tags (at most 64)");
    for (const std::string& t : *update.tags) {
      if (t.size() > kMaxTag)
        throw RequestError(StatusCode::kInvalidArgument,
                           "tags",
                           "tags: a tag longer than 64 characters");
      CheckText(t, "tags", kMaxTag);
    }
  }
  Material m;
  m.id = id;
  if (auto old = store_->GetMaterial(id)) m = *old;
  if (update.name) m.name = *update.name;
  if (update.description) m.description = *update.description;
  if (update.tags) m.tags = *update.tags;
  if (m.name.empty()) m.name = id;
  return store_->PutMaterial(m);
}

bool FrictionLibrary::PutFingertip(const Fingertip& fingertip) {
  CheckId(fingertip.id, "id");
  constexpr std::size_t kMaxFingertipText = 4000;
  // The text rules of a material's name and description.
  CheckText(fingertip.name, "name", kMaxFingertipText);
  CheckFreeText(fingertip.description, "description", kMaxFingertipText);
  return store_->PutFingertip(fingertip);
}

bool FrictionLibrary::PutRobot(const std::string& id,
                               const RobotDescription& robot) {
  CheckId(id, "id");
  for (std::size_t i = 0; i < robot.friction.size(); ++i) {
    if (!robot.friction[i]) continue;
    const std::string at = "joints[" + std::to_string(i) + "].friction.";
    for (const auto& [name, value] :
         {std::pair<const char*, const std::string*>{
              "material", &robot.friction[i]->material},
          {"joint", &robot.friction[i]->joint}}) {
      if (!IsValidId(*value))
        throw RequestError(StatusCode::kInvalidArgument,
                           at + name,
                           at + name + " = '" + ShownText(*value, 64) +
                               "' (must match [A-Za-z0-9._-]{1,64})");
    }
  }
  return store_->PutRobot(RobotRecord{id, RobotToJson(robot).dump(), "", ""});
}

void FrictionLibrary::RequireImageMaterial(const std::string& id) {
  CheckId(id, "id");
  if (!store_->GetMaterial(id))
    throw RequestError(StatusCode::kNotFound,
                       "id",
                       "unknown material '" + id +
                           "' (create it with PUT /v1/materials/" + id +
                           " first)");
}

std::int64_t FrictionLibrary::AddReferenceImage(const ImageRecord& image) {
  RequireImageMaterial(image.material);
  return store_->AddImage(image);
}

bool FrictionLibrary::DeleteMaterial(const std::string& id) {
  CheckId(id, "id");
  const bool deleted = store_->DeleteMaterial(id);
  ingestor_->Invalidate(id, "");
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

StrokePlan FrictionLibrary::MakeStrokePlan(const std::string& material,
                                           const std::string& fingertip) const {
  return jobs_.MakeStrokePlan(material, fingertip);
}

IdentificationRequest FrictionLibrary::RequestIdentification(
    const std::string& material,
    const std::string& fingertip,
    const std::string& requested_by) {
  return jobs_.Request(material, fingertip, requested_by);
}

std::shared_ptr<const CachedModel> FrictionLibrary::RequireModel(
    const std::string& material,
    const std::string& fingertip,
    const std::string& requested_by) {
  const ModelLookup found =
      LookUpModel(*this, material, fingertip, requested_by);
  if (found.model) return found.model;
  json extra = json{{"material", material},
                    {"fingertip", fingertip},
                    {"known_material", found.known_material}};
  extra["identification"] = IdentificationRequestToJson(found.identification);
  throw RequestError(StatusCode::kNotFound, "id", found.message, extra);
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
  for (const StrokeRecord& s :
       store_->ListStrokesAfter(material, fingertip, 0, /*with_csv=*/true)) {
    StrokeData d = ParseStrokeCsv(
        s.csv, StrokeCsvOptions{options_.max_samples_per_upload, 64});
    PrepareUpload(&d, *labelling);
    all.Append(d);
  }
  return all;
}

IngestResult FrictionLibrary::IngestStrokes(const std::string& material,
                                            const std::string& csv,
                                            const IngestOptions& options) {
  CheckId(material, "id");
  CheckId(options.fingertip, "fingertip");
  if (options.robot.size() > 128)
    throw RequestError(
        StatusCode::kInvalidArgument, "robot", "robot: at most 128 characters");
  // 0. Memory: large uploads one at a time (LibraryOptions), refused
  // before they are parsed.
  struct LargeSlot {
    std::atomic<int>* count = nullptr;
    ~LargeSlot() {
      if (count) --*count;
    }
  } large;
  if (csv.size() > options_.large_upload_bytes) {
    if (++large_uploads_ > options_.max_large_uploads) {
      --large_uploads_;
      throw RequestError(StatusCode::kUnavailable,
                         "body",
                         "body: " + std::to_string(csv.size()) +
                             " bytes; another upload of more than " +
                             std::to_string(options_.large_upload_bytes) +
                             " bytes is being processed (at most " +
                             std::to_string(options_.max_large_uploads) +
                             " at once, for memory): retry when it is done");
    }
    large.count = &large_uploads_;
  }
  // 1. Validate the upload completely before touching the store.
  StrokeData upload;
  try {
    upload = ParseStrokeCsv(
        csv, StrokeCsvOptions{options_.max_samples_per_upload, 64});
  } catch (const StrokeCsvError& e) {
    throw RequestError(e.too_large() ? StatusCode::kResourceExhausted
                                     : StatusCode::kInvalidArgument,
                       e.field(),
                       e.what(),
                       json{{"line", e.line()}});
  }
  // 2. One upload of the pair at a time, in arrival order.
  Ingestor::PairLock pair = ingestor_->Lock(material, options.fingertip);
  // Counted from here to the commit: whether a refit splits depends on the
  // uploads in flight, not only on the refits (fit_workers.h).
  const FitWorkers::InFlight slot = fit_workers_->Begin();
  // 3. Labelling: explicit, else the pair's previous one, else defaults.
  SlipLabelOptions labelling;
  auto previous = FindModel(material, options.fingertip);
  if (options.labelling) {
    labelling = *options.labelling;
  } else if (previous && previous->set.stochastic) {
    labelling = previous->set.stochastic->labelling;
  }
  // 4. The refit's data: the pair's cached uploads (bounded) + this one.
  const std::size_t n_new = upload.size();
  PrepareUpload(&upload, labelling);
  const FitData data = ingestor_->AssembleFitData(pair, labelling, upload);
  ModelSetFit fit = FitModelSet(material,
                                options.fingertip,
                                data.strokes,
                                upload,
                                previous.get(),
                                labelling,
                                slot,
                                &pair.memo(),
                                &pair.conditional_start());
  if (fit.status != FitStatus::kOk && fit.status != FitStatus::kPartial) {
    throw RequestError(
        StatusCode::kFailedPrecondition,
        fit.field.empty() ? "body" : fit.field,
        "stroke accepted as CSV but no model can be identified: " + fit.why,
        json{{"fit_status", ToString(fit.status)}});
  }
  // 5. One transaction: stroke + model version.
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
  json doc = ModelSetToJson(fit.set);
  doc.erase("version");
  doc.erase("created_at");
  record.json = doc.dump();
  std::optional<AuditEntry> audit = options.audit;
  if (audit) {
    json detail = audit->detail.empty()
                      ? json::object()
                      : json::parse(audit->detail, nullptr, false);
    if (detail.is_object()) {  // otherwise CommitUpload refuses it
      detail["fingertip"] = options.fingertip;
      detail["samples"] = n_new;
      detail["fit_status"] = ToString(fit.status);
      audit->detail = detail.dump();
    }
  }
  const UploadCommit commit =
      store_->CommitUpload(stroke, record, audit ? &*audit : nullptr);
  // 6. The committed version, from what was committed (no re-read).
  record.version = commit.version;
  record.created_at = commit.created_at;
  record.stroke_id = commit.stroke_id;
  IngestResult out;
  out.stroke_id = commit.stroke_id;
  out.version = commit.version;
  out.material_created = commit.material_created;
  out.samples = n_new;
  out.model = Publish(doc, record);
  ingestor_->Append(pair, commit.stroke_id, std::move(upload));
  out.fit_status = ToString(fit.status);
  out.fit_note = fit.why;
  if (data.uploads_used < data.uploads_stored) {
    out.fit_note +=
        (out.fit_note.empty() ? "" : "; ") + std::string("bounded refit: ") +
        std::to_string(data.uploads_used) + " of " +
        std::to_string(data.uploads_stored) + " stored uploads (" +
        std::to_string(data.samples_used) + " of " +
        std::to_string(data.samples_stored) + " samples) with this one";
  }
  if (!fit.note.empty())
    out.fit_note += (out.fit_note.empty() ? "" : "; ") + fit.note;
  Notify(out.model);
  return out;
}

FrictionLibrary::ModelSetFit FrictionLibrary::FitModelSet(
    const std::string& material,
    const std::string& fingertip,
    const StrokeData& strokes,
    const StrokeData& upload,
    const CachedModel* previous,
    const SlipLabelOptions& labelling,
    const FitWorkers::InFlight& slot,
    IdentificationMemo* memo,
    ConditionalSlipLikelihood* conditional_start) const {
  StochasticFitOptions fit_options;
  if (previous && previous->set.stochastic) {
    // Keep an extended model's terms (product columns included) and its eps
    // scale when they can be computed from the data.
    fit_options = CalcRefitOptions(*previous->set.stochastic, strokes);
  }
  fit_options.labelling = labelling;
  // Every built-in family comes from the one estimators entry point
  // (identification.h: eq. (1) with eps, eq. (2), LuGre from recognised
  // strokes, coverage), so `bench/run identify_material` times what an
  // upload does. Families registered with AddFamilyFitter (extensions) read
  // only the data and run beside it on another thread.
  struct FamilyFit {
    std::string family;
    json model;
    std::string note;
  };
  std::future<std::vector<FamilyFit>> families;
  if (!fitters_.empty()) {
    families =
        std::async(std::launch::async, [this, &strokes, &upload, previous] {
          std::vector<FamilyFit> out;
          for (const auto& [family, fitter] : fitters_) {
            FamilyFit f{family, nullptr, ""};
            f.model = fitter(strokes, upload, previous, &f.note);
            out.push_back(std::move(f));
          }
          return out;
        });
  }
  auto wait_families = [&families] {
    if (families.valid()) families.wait();  // it reads `strokes`
  };
  MaterialIdentificationOptions id_options;
  id_options.fit = fit_options;
  id_options.memo = memo;  // the pair's: its older strokes' steps kept
  id_options.conditional_start = conditional_start;
  if (slot.split()) {
    id_options.post = [this](std::function<void()> task) {
      fit_workers_->PostShare(std::move(task));
    };
  } else {
    id_options.threads = 1;  // every core already serves a refit
  }
  const StrokePlanOptions& plan = options_.plan;
  id_options.reference = {
      plan.fn_min_n, plan.fn_max_n, plan.v_min_mm_s, plan.v_max_mm_s};
  ModelSetFit out;
  MaterialIdentification id;
  try {
    id = IdentifyMaterial(strokes, id_options);
  } catch (...) {
    wait_families();
    throw;
  }
  StochasticFit& fit = id.fit;
  out.status = fit.status;
  out.why = fit.why;
  out.field = fit.field;
  if (fit.status != FitStatus::kOk && fit.status != FitStatus::kPartial) {
    wait_families();
    return out;
  }
  out.set.material = material;
  out.set.fingertip = fingertip;
  out.set.stochastic = std::move(fit.model);
  if (previous) {
    for (auto it = previous->set.other.begin(); it != previous->set.other.end();
         ++it) {
      if (it.key() != "reason") out.set.other[it.key()] = *it;
    }
  }
  auto add_note = [&out](const std::string& family, const std::string& note) {
    if (!note.empty())
      out.note += (out.note.empty() ? "" : "; ") + family + ": " + note;
  };
  // A family the data cannot identify keeps its previous version, if any.
  if (id.conditional.valid) {
    out.set.other[kConditionalSlipFamilyKey] =
        ConditionalSlipToJson(id.conditional);
    if (conditional_start) *conditional_start = std::move(id.conditional);
  } else {
    add_note(kConditionalSlipFamilyKey, id.conditional.why);
  }
  if (id.lugre.identified) {
    out.set.other[kLuGreFamilyKey] = LuGreToJson(id.lugre.family);
  } else {
    add_note(kLuGreFamilyKey, id.lugre.why);
  }
  if (families.valid()) {
    for (FamilyFit& f : families.get()) {
      if (!f.model.is_null()) out.set.other[f.family] = std::move(f.model);
      add_note(f.family, f.note);
    }
  }
  return out;
}

std::shared_ptr<const CachedModel> FrictionLibrary::Publish(
    const json& doc, const ModelRecord& record) {
  // What Decode(record) would give, built from the committed document
  // (no text round trip through the store).
  auto cm = std::make_shared<CachedModel>();
  cm->set = ModelSetFromJson(doc);
  cm->set.material = record.material;
  cm->set.fingertip = record.fingertip;
  cm->set.version = record.version;
  cm->set.created_at = record.created_at;
  json out = ModelSetToJson(cm->set);
  out["reason"] = record.reason;
  cm->json_text = out.dump();
  const std::string key = Key(record.material, record.fingertip);
  std::unique_lock lock(cache_mu_);
  ++cache_gen_;  // a read racing with this commit does not cache
  stale_.erase(key);
  auto& slot = cache_[key];
  if (!slot || slot->set.version < cm->set.version) slot = cm;
  return cm;
}

std::shared_ptr<const CachedModel> FrictionLibrary::AddModelVersion(
    const std::string& material,
    const std::string& fingertip,
    const StochasticFrictionModel& model,
    const std::string& reason,
    const json& extra_families) {
  Ingestor::PairLock pair = ingestor_->Lock(material, fingertip);
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
  Ingestor::PairLock pair = ingestor_->Lock(material, fingertip);
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
  ingestor_->Invalidate(material, fingertip);
  Invalidate(material, fingertip);
}

void FrictionLibrary::InvalidateAllCached() {
  ingestor_->Invalidate("", "");
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
    PutMaterial(id, BundledMaterial(d, id));
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
      PutMaterial(robot, BundledMaterial(d, robot));
      ++loaded;
    }
  }
  return loaded;
}

}  // namespace frictiond

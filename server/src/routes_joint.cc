// Joint friction and repeatability (paper 002, issue 9 item 5): the "joint"
// model family of (material, joint id) pairs, stored beside the other
// families of the pair's model versions (the joint id takes the fingertip's
// place), and robot descriptions for repeatability ellipsoids.
//
//   POST /v1/materials/{id}/joint-data?joint=&area_mm2=&...   (text/csv)
//   GET  /v1/materials/{id}/joint-friction?v_mm_s=&load_n=&temp_c=|eta_pa_s=
//   GET  /v1/materials/{id}/joint-wear?v_mm_s=&load_n=&temp_c=&distance_mm=
//   PUT  /v1/robots/{id}                                       (JSON)
//   GET  /v1/robots/{id}
//   GET  /v1/robots/{id}/repeatability?x_mm=&y_mm=&z_mm=&probability=
//   GET  /v1/robots/{id}/repeatability-grid?z_mm=&x0_mm=&y0_mm=&size_mm=&n=
//
// Shapes and rules: docs/joint.md.
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "frictiond/estimators/joint_friction.h"
#include "frictiond/estimators/joint_identification.h"
#include "frictiond/estimators/number_text.h"
#include "frictiond/estimators/repeatability.h"
#include "frictiond/proto/joint_json.h"
#include "frictiond/server/model_lookup.h"
#include "frictiond/server/routes.h"

namespace frictiond {

using nlohmann::json;

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr std::size_t kMaxJointRows = 200000;
constexpr int kMinJointSamples = 10;

double PositiveParam(const HttpRequest& req, const std::string& name) {
  const double x = req.RequireNumber(name);
  if (!(x > 0))
    throw RequestError(StatusCode::kInvalidArgument,
                       name,
                       name + " = " + NumberText(x) + " (must be > 0)");
  return x;
}

void OptionalParam(const HttpRequest& req, const char* name, double* x) {
  if (auto v = req.Query(name)) *x = ParseNumberParam(name, *v);
}

std::string JointParam(const HttpRequest& req) {
  const std::string j = req.QueryOr("joint", "default");
  CheckId(j, "joint");
  return j;
}

json Finite(double x) { return std::isfinite(x) ? json(x) : json(); }

// --------------------------------------------------------------- upload

HttpResponse HandleUpload(FrictionLibrary& lib, const HttpRequest& req) {
  const std::string& id = req.params.at(0);
  CheckId(id, "id");
  const std::string joint = JointParam(req);
  const std::string ct = req.Header("Content-Type");
  if (ct.rfind("text/csv", 0) != 0)
    throw HttpError(
        415,
        "Content-Type",
        "Content-Type '" + ct.substr(0, 64) + "' (must be text/csv)");
  JointFamily family;
  JointConfig& c = family.config;
  OptionalParam(req, "area_mm2", &c.contact.area_mm2);
  OptionalParam(req, "alt_um", &c.surface.alt_um);
  OptionalParam(req, "salt_um", &c.surface.salt_um);
  OptionalParam(req, "radius_log_sd", &c.surface.radius_log_sd);
  OptionalParam(req, "radius_log_mean", &c.surface.radius_log_mean);
  OptionalParam(req, "srad_um", &c.surface.srad_um);
  OptionalParam(req, "summits", &c.surface.summits);
  OptionalParam(req, "modulus_gpa", &c.surface.modulus_gpa);
  OptionalParam(req, "vogel_a_pa_s", &c.lubricant.vogel_a_pa_s);
  OptionalParam(req, "vogel_b_c", &c.lubricant.vogel_b_c);
  OptionalParam(req, "vogel_c_c", &c.lubricant.vogel_c_c);
  OptionalParam(req, "k_solid", &family.wear.k_solid);
  OptionalParam(req, "hardness_mpa", &family.wear.hardness_mpa);
  double folds = 5;
  OptionalParam(req, "folds", &folds);
  if (!(folds >= 2 && folds <= 20 && folds == std::floor(folds)))
    throw RequestError(
        StatusCode::kInvalidArgument,
        "folds",
        "folds = " + NumberText(folds) + " (must be an integer 2..20)");
  if (!(c.contact.area_mm2 > 0))
    throw RequestError(
        StatusCode::kInvalidArgument,
        "area_mm2",
        "area_mm2 = " + NumberText(c.contact.area_mm2) + " (must be > 0)");
  if (!(family.wear.k_solid >= 0))
    throw RequestError(
        StatusCode::kInvalidArgument,
        "k_solid",
        "k_solid = " + NumberText(family.wear.k_solid) + " (must be >= 0)");
  if (!(family.wear.hardness_mpa > 0))
    throw RequestError(
        StatusCode::kInvalidArgument,
        "hardness_mpa",
        "hardness_mpa = " + NumberText(family.wear.hardness_mpa) +
            " (must be > 0)");
  JointData data;
  try {
    ValidateSurface(c.surface);
    ValidateLubricant(c.lubricant);
    data = ParseJointCsv(req.body, c.lubricant, kMaxJointRows);
    ValidateJointData(data);
  } catch (const std::invalid_argument& e) {
    throw InvalidArgumentFrom(e, "body");
  }
  if (data.size() < static_cast<std::size_t>(kMinJointSamples))
    throw RequestError(StatusCode::kFailedPrecondition,
                       "body",
                       std::to_string(data.size()) + " samples (at least " +
                           std::to_string(kMinJointSamples) + " needed)");
  family.samples = data.size();
  family.v_min_mm_s = *std::min_element(data.v_mm_s.begin(), data.v_mm_s.end());
  family.v_max_mm_s = *std::max_element(data.v_mm_s.begin(), data.v_mm_s.end());
  family.load_min_n = *std::min_element(data.load_n.begin(), data.load_n.end());
  family.load_max_n = *std::max_element(data.load_n.begin(), data.load_n.end());
  family.s_min_um = std::numeric_limits<double>::infinity();
  family.s_max_um = 0;
  for (std::size_t i = 0; i < data.size(); ++i) {
    const double s = CalcSommerfeldUm(
        data.eta_pa_s[i], data.v_mm_s[i], data.load_n[i], c.contact);
    family.s_min_um = std::min(family.s_min_um, s);
    family.s_max_um = std::max(family.s_max_um, s);
  }
  family.mixed = FitJointModel(JointModelKind::kMixed, data, c);
  family.stribeck = FitJointModel(JointModelKind::kStribeckViscous, data, c);
  family.lugre = FitJointModel(JointModelKind::kLuGreSteadyState, data, c);
  family.scores = CompareJointModels(data, c, static_cast<int>(folds));
  const json fj = JointFamilyToJson(family);
  auto model =
      lib.AddFamilyVersion(id, joint, kJointFamilyKey, fj, "joint-data");
  json body = {{"material", id},
               {"joint", joint},
               {"version", model ? model->set.version : 0},
               {"family", fj}};
  return HttpResponse::Json(201, body);
}

// --------------------------------------------------------------- queries

struct LoadedFamily {
  std::shared_ptr<const CachedModel> model;
  JointFamily family;
};

LoadedFamily LoadFamily(FrictionLibrary& lib,
                        const std::string& material,
                        const std::string& joint,
                        const HttpRequest* req) {
  CheckId(material, "id");
  const json upload_hint = {{"upload",
                             "POST /v1/materials/" + material +
                                 "/joint-data?joint=" + joint +
                                 " (text/csv: v_mm_s, "
                                 "load_n, mu, temp_c or eta_pa_s)"}};
  std::optional<int> version;
  if (req) {
    if (auto v = req->Query("version")) version = ParseVersionParam(*v);
  }
  const ModelFamily found = RequireModelFamily(
      lib, material, joint, version, kJointFamilyKey, "joint", upload_hint);
  LoadedFamily out;
  out.model = found.model;
  try {
    out.family = JointFamilyFromJson(*found.family);
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(std::string("stored joint family is malformed: ") +
                             e.what());
  }
  return out;
}

// State of a query: speed, load and viscosity (eta_pa_s or temp_c).
struct JointQueryState {
  double v_mm_s = 0, load_n = 0, eta_pa_s = 0, s_um = 0;
  double temp_c = std::numeric_limits<double>::quiet_NaN();
};

JointQueryState ParseState(const HttpRequest& req, const JointConfig& c) {
  JointQueryState s;
  s.v_mm_s = PositiveParam(req, "v_mm_s");
  s.load_n = PositiveParam(req, "load_n");
  if (req.Query("eta_pa_s")) {
    s.eta_pa_s = PositiveParam(req, "eta_pa_s");
  } else if (req.Query("temp_c")) {
    s.temp_c = req.RequireNumber("temp_c");
    s.eta_pa_s = CalcViscosity(c.lubricant, s.temp_c);
    if (!(s.eta_pa_s > 0 && std::isfinite(s.eta_pa_s)))
      throw RequestError(StatusCode::kInvalidArgument,
                         "temp_c",
                         "temp_c = " + NumberText(s.temp_c) +
                             " (outside the lubricant's Vogel range)");
  } else {
    throw RequestError(StatusCode::kInvalidArgument,
                       "temp_c",
                       "temp_c or eta_pa_s is required");
  }
  s.s_um = CalcSommerfeldUm(s.eta_pa_s, s.v_mm_s, s.load_n, c.contact);
  return s;
}

bool Usable(const JointFitResult& r) {
  return (r.status == JointFitStatus::kConverged ||
          r.status == JointFitStatus::kMaxIterations) &&
         r.theta.size() == 4 && r.theta.allFinite();
}

HttpResponse HandleFriction(FrictionLibrary& lib, const HttpRequest& req) {
  const std::string joint = JointParam(req);
  const LoadedFamily lf = LoadFamily(lib, req.params.at(0), joint, &req);
  const JointFamily& f = lf.family;
  const JointQueryState st = ParseState(req, f.config);
  json body = {{"material", req.params.at(0)},
               {"joint", joint},
               {"version", lf.model->set.version},
               {"v_mm_s", st.v_mm_s},
               {"load_n", st.load_n},
               {"eta_pa_s", st.eta_pa_s},
               {"temp_c", Finite(st.temp_c)},
               {"sommerfeld_um", st.s_um},
               {"in_span", st.s_um >= f.s_min_um && st.s_um <= f.s_max_um}};
  json classic = json::object();
  for (const JointFitResult* r : {&f.stribeck, &f.lugre}) {
    if (r->theta.allFinite() && r->status != JointFitStatus::kFailed &&
        r->status != JointFitStatus::kNotObservable) {
      classic[ToString(r->kind)] = PredictJointFriction(
          r->kind, r->theta, f.config, st.v_mm_s, st.load_n, st.eta_pa_s);
    } else {
      classic[ToString(r->kind)] = nullptr;
    }
  }
  body["classic"] = classic;
  if (!Usable(f.mixed)) {
    throw RequestError(StatusCode::kFailedPrecondition,
                       "joint",
                       "the mixed model of this joint is not identified (" +
                           ToString(f.mixed.status) +
                           (f.mixed.why.empty() ? "" : ": ") + f.mixed.why +
                           "); upload data spanning the Sommerfeld number",
                       body);
  }
  const MixedFrictionPrediction p =
      PredictMixedFriction(f.mixed, f.config.surface, st.s_um, st.load_n);
  if (!std::isfinite(p.mu) || !std::isfinite(p.sigma) ||
      !std::isfinite(p.alpha) || !std::isfinite(st.s_um)) {
    // Never 200 with null numbers: the inputs overflow the model (e.g.
    // load_n = 4.9e-324 or v_mm_s = 1e300). Named: the more extreme of the
    // two (farther from 1 in orders of magnitude).
    const bool load = std::abs(std::log10(st.load_n)) >=
                      std::abs(std::log10(std::max(st.v_mm_s, 1e-300)));
    throw RequestError(
        StatusCode::kFailedPrecondition,
        load ? "load_n" : "v_mm_s",
        "no finite prediction at v_mm_s = " + NumberText(st.v_mm_s) +
            ", load_n = " + NumberText(st.load_n) + " (Sommerfeld number " +
            NumberText(st.s_um) + " um): the model's terms overflow there");
  }
  body["mu"] = p.mu;
  body["sigma"] = p.sigma;
  body["sigma_contact"] = p.sigma_contact;
  body["sigma_param"] = p.sigma_param;
  body["interval95"] = {p.lo95, p.hi95};
  body["floored_at_zero"] = p.floored_at_zero;
  body["film_um"] = p.film_um;
  body["alpha"] = p.alpha;
  body["regime"] = p.alpha > 0.99   ? "boundary"
                   : p.alpha < 0.01 ? "full_film"
                                    : "mixed";
  body["wear_coefficient"] = CalcWearCoefficient(
      f.mixed.theta.head<4>(), f.config.surface, f.wear, st.s_um, st.load_n);
  return HttpResponse::Json(200, body);
}

HttpResponse HandleWear(FrictionLibrary& lib, const HttpRequest& req) {
  const std::string joint = JointParam(req);
  const LoadedFamily lf = LoadFamily(lib, req.params.at(0), joint, &req);
  const JointFamily& f = lf.family;
  const JointQueryState st = ParseState(req, f.config);
  const double distance = PositiveParam(req, "distance_mm");
  double points = 11;
  OptionalParam(req, "points", &points);
  if (!(points >= 2 && points <= 1000 && points == std::floor(points)))
    throw RequestError(
        StatusCode::kInvalidArgument,
        "points",
        "points = " + NumberText(points) + " (must be an integer 2..1000)");
  if (!Usable(f.mixed))
    throw RequestError(StatusCode::kFailedPrecondition,
                       "joint",
                       "the mixed model of this joint is not identified");
  std::vector<WearPoint> run;
  try {
    run = PredictWearDrift(f.mixed.theta.head<4>(),
                           f.config.surface,
                           f.wear,
                           f.config.contact,
                           st.s_um,
                           st.load_n,
                           distance,
                           static_cast<int>(points));
  } catch (const std::invalid_argument& e) {
    throw InvalidArgumentFrom(e, "distance_mm");
  }
  json pts = json::array();
  for (const WearPoint& w : run)
    pts.push_back({{"distance_mm", w.distance_mm},
                   {"worn_um", w.worn_um},
                   {"mu", w.friction},
                   {"wear_coefficient", w.wear_coefficient}});
  return HttpResponse::Json(200,
                            json{{"material", req.params.at(0)},
                                 {"joint", joint},
                                 {"version", lf.model->set.version},
                                 {"sommerfeld_um", st.s_um},
                                 {"points", pts}});
}

// --------------------------------------------------------------- robots

RobotDescription LoadRobot(FrictionLibrary& lib, const std::string& id) {
  CheckId(id, "id");
  auto rec = lib.store().GetRobot(id);
  if (!rec)
    throw RequestError(StatusCode::kNotFound,
                       "id",
                       "robot '" + id + "' is not known (PUT /v1/robots/" + id +
                           " with its DH parameters and joint stiffness)");
  try {
    return RobotFromJson(json::parse(rec->json));
  } catch (const std::exception& e) {
    throw std::runtime_error(std::string("stored robot is malformed: ") +
                             e.what());
  }
}

// Fills each joint's sigma_tau from its friction reference.
json ResolveFriction(FrictionLibrary& lib, RobotDescription* robot) {
  json sources = json::array();
  for (std::size_t i = 0; i < robot->arm.joints.size(); ++i) {
    DhJoint& j = robot->arm.joints[i];
    if (!robot->friction[i]) {
      sources.push_back({{"sigma_tau", j.sigma_tau}, {"source", "given"}});
      continue;
    }
    const JointFrictionRef& ref = *robot->friction[i];
    const std::string at = "joints[" + std::to_string(i) + "].friction";
    LoadedFamily lf;
    try {
      lf = LoadFamily(lib, ref.material, ref.joint, nullptr);
    } catch (const RequestError& e) {
      throw RequestError(
          StatusCode::kFailedPrecondition, at, at + ": " + e.what());
    }
    if (!Usable(lf.family.mixed))
      throw RequestError(StatusCode::kFailedPrecondition,
                         at,
                         at + ": the mixed model of '" + ref.material +
                             "' joint '" + ref.joint + "' is not identified");
    const double eta = CalcViscosity(lf.family.config.lubricant, ref.temp_c);
    const double s =
        CalcSommerfeldUm(eta, ref.v_mm_s, ref.load_n, lf.family.config.contact);
    const MixedFrictionPrediction p = PredictMixedFriction(
        lf.family.mixed, lf.family.config.surface, s, ref.load_n);
    const double lever =
        j.type == JointType::kRevolute ? ref.radius_mm / 1000.0 : 1.0;
    j.sigma_tau = p.sigma * ref.load_n * lever;
    sources.push_back({{"sigma_tau", j.sigma_tau},
                       {"source", "joint model"},
                       {"material", ref.material},
                       {"joint", ref.joint},
                       {"version", lf.model->set.version},
                       {"mu", p.mu},
                       {"sigma_mu", p.sigma},
                       {"sommerfeld_um", s}});
  }
  return sources;
}

json MatrixToJson(const Eigen::Matrix3d& m, double scale) {
  json a = json::array();
  for (int i = 0; i < 3; ++i)
    a.push_back({m(i, 0) * scale, m(i, 1) * scale, m(i, 2) * scale});
  return a;
}

double Probability(const HttpRequest& req) {
  double c = 0.95;
  OptionalParam(req, "probability", &c);
  if (!(c > 0 && c < 1))
    throw RequestError(
        StatusCode::kInvalidArgument,
        "probability",
        "probability = " + NumberText(c) + " (must be in (0, 1))");
  return c;
}

HttpResponse HandleRepeatability(FrictionLibrary& lib, const HttpRequest& req) {
  const std::string& id = req.params.at(0);
  const Eigen::Vector3d target(req.RequireNumber("x_mm"),
                               req.RequireNumber("y_mm"),
                               req.RequireNumber("z_mm"));
  const double c = Probability(req);
  RobotDescription robot = LoadRobot(lib, id);
  const json sources = ResolveFriction(lib, &robot);
  const IkResult ik = SolvePositionIk(robot.arm, target, robot.q_home);
  if (!ik.converged)
    throw RequestError(StatusCode::kFailedPrecondition,
                       "x_mm",
                       "(" + NumberText(target[0]) + ", " +
                           NumberText(target[1]) + ", " +
                           NumberText(target[2]) + ") mm: " + ik.why);
  const Ellipsoid e = CalcRepeatabilityEllipsoid(robot.arm, ik.q, c);
  json q = json::array();
  for (Eigen::Index i = 0; i < ik.q.size(); ++i) {
    const bool rev = robot.arm.joints[static_cast<std::size_t>(i)].type ==
                     JointType::kRevolute;
    q.push_back(ik.q[i] * (rev ? 180.0 / kPi : 1.0));
  }
  json axes = json::array();
  for (int i = 0; i < 3; ++i)
    axes.push_back({e.axes(0, i), e.axes(1, i), e.axes(2, i)});
  return HttpResponse::Json(
      200,
      json{{"robot", id},
           {"target_mm", {target[0], target[1], target[2]}},
           {"q", q},
           {"ik_error_mm", ik.error_mm},
           {"probability", c},
           {"rank", e.rank},
           {"chi2", e.chi2},
           {"semi_axes_um",
            {e.semi_axes_mm[0] * 1e3,
             e.semi_axes_mm[1] * 1e3,
             e.semi_axes_mm[2] * 1e3}},
           {"axes", axes},
           {"covariance_um2", MatrixToJson(e.P_x, 1e6)},
           {"joints", sources}});
}

HttpResponse HandleGrid(FrictionLibrary& lib, const HttpRequest& req) {
  const std::string& id = req.params.at(0);
  const double z = req.RequireNumber("z_mm");
  const double x0 = req.RequireNumber("x0_mm");
  const double y0 = req.RequireNumber("y0_mm");
  double size = 400, n = 10;
  OptionalParam(req, "size_mm", &size);
  OptionalParam(req, "n", &n);
  if (!(size > 0 && size <= 1e5))
    throw RequestError(
        StatusCode::kInvalidArgument,
        "size_mm",
        "size_mm = " + NumberText(size) + " (must be in (0, 1e5])");
  if (!(n >= 2 && n <= 100 && n == std::floor(n)))
    throw RequestError(StatusCode::kInvalidArgument,
                       "n",
                       "n = " + NumberText(n) + " (must be an integer 2..100)");
  const double c = Probability(req);
  RobotDescription robot = LoadRobot(lib, id);
  const json sources = ResolveFriction(lib, &robot);
  const int k = static_cast<int>(n);
  const auto grid = CalcEllipsoidGrid(
      robot.arm, x0, y0, size, size, z, k, k, robot.q_home, c);
  json pts = json::array();
  for (const GridEllipsoid& g : grid) {
    pts.push_back({{"x_mm", g.target_mm[0]},
                   {"y_mm", g.target_mm[1]},
                   {"reachable", g.reachable},
                   {"semi_axes_um",
                    g.reachable ? json{g.semi_axes_mm[0] * 1e3,
                                       g.semi_axes_mm[1] * 1e3,
                                       g.semi_axes_mm[2] * 1e3}
                                : json()}});
  }
  return HttpResponse::Json(200,
                            json{{"robot", id},
                                 {"z_mm", z},
                                 {"n", k},
                                 {"size_mm", size},
                                 {"probability", c},
                                 {"points", pts},
                                 {"joints", sources}});
}

HttpResponse HandlePutRobot(FrictionLibrary& lib, const HttpRequest& req) {
  const std::string& id = req.params.at(0);
  CheckId(id, "id");
  const json j = ParseJsonBody(req.body);
  RobotDescription robot;
  try {
    robot = RobotFromJson(j);
  } catch (const std::invalid_argument& e) {
    throw InvalidArgumentFrom(e, "body");
  }
  const bool created = lib.PutRobot(id, robot);
  const json doc = RobotToJson(robot);
  json body = doc;
  body["robot"] = id;
  return HttpResponse::Json(created ? 201 : 200, body);
}

}  // namespace

void RegisterJointRoutes(HttpServer& http, FrictionLibrary& library) {
  http.Route("POST",
             "/v1/materials/{id}/joint-data",
             [&library](const HttpRequest& req) {
               return HandleUpload(library, req);
             });
  http.Route("GET",
             "/v1/materials/{id}/joint-friction",
             [&library](const HttpRequest& req) {
               return HandleFriction(library, req);
             });
  http.Route(
      "GET",
      "/v1/materials/{id}/joint-wear",
      [&library](const HttpRequest& req) { return HandleWear(library, req); });
  http.Route("PUT", "/v1/robots/{id}", [&library](const HttpRequest& req) {
    return HandlePutRobot(library, req);
  });
  http.Route("GET", "/v1/robots/{id}", [&library](const HttpRequest& req) {
    RobotDescription r = LoadRobot(library, req.params.at(0));
    json body = RobotToJson(r);
    body["robot"] = req.params.at(0);
    return HttpResponse::Json(200, body);
  });
  http.Route("GET",
             "/v1/robots/{id}/repeatability",
             [&library](const HttpRequest& req) {
               return HandleRepeatability(library, req);
             });
  http.Route(
      "GET",
      "/v1/robots/{id}/repeatability-grid",
      [&library](const HttpRequest& req) { return HandleGrid(library, req); });
}

}  // namespace frictiond

#include "frictiond/estimators/regression.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "frictiond/estimators/number_text.h"
#include "frictiond/estimators/simd.h"
#include "frictiond/estimators/stats.h"

namespace frictiond {

namespace {

bool EndsWith(std::string_view s, std::string_view suffix) {
  return s.size() >= suffix.size() &&
         s.substr(s.size() - suffix.size()) == suffix;
}

double ParseNumber(std::string_view s, std::string_view whole) {
  double x = 0;
  auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), x);
  if (ec != std::errc() || p != s.data() + s.size() || !std::isfinite(x)) {
    throw std::invalid_argument("term '" + std::string(whole) + "': '" +
                                std::string(s) + "' is not a number");
  }
  return x;
}

}  // namespace

const char* ToString(FitStatus s) {
  switch (s) {
    case FitStatus::kOk:
      return "ok";
    case FitStatus::kPartial:
      return "partial";
    case FitStatus::kTooFewSamples:
      return "too_few_samples";
    case FitStatus::kFailed:
      return "failed";
  }
  return "unknown";
}

std::string Term::Name() const {
  switch (kind) {
    case TermKind::kIntercept:
      return "intercept";
    case TermKind::kLinear:
      return input;
    case TermKind::kPower:
      return input + "^" + NumberText(a);
    case TermKind::kLog:
      return "log(" + input + ")";
    case TermKind::kSin:
      return "sin(" + input + ")";
    case TermKind::kCos:
      return "cos(" + input + ")";
    case TermKind::kExpDecay:
      return "exp(-" + input + "/" + NumberText(a) + ")";
    case TermKind::kWindow:
      return "in(" + input + "," + NumberText(a) + "," + NumberText(b) + ")";
    case TermKind::kHinge:
      return "hinge(" + input + "," + NumberText(a) + ")";
    case TermKind::kSinDeg:
      return "sind(" + input + ")";
    case TermKind::kCosDeg:
      return "cosd(" + input + ")";
    case TermKind::kOnsetDecay:
      return "onset(" + input + "," + NumberText(a) +
             (b == 1.0 ? std::string() : "," + NumberText(b)) + ")";
  }
  return "?";
}

Term Term::Parse(std::string_view name) {
  auto bad = [&](const std::string& why) {
    return std::invalid_argument("term '" + std::string(name) + "': " + why);
  };
  if (name.empty()) throw bad("empty name");
  if (name == "intercept") return Intercept();
  auto inner = [&](std::string_view prefix) -> std::string_view {
    if (name.substr(0, prefix.size()) != prefix || name.back() != ')')
      return {};
    return name.substr(prefix.size(), name.size() - prefix.size() - 1);
  };
  Term t;
  if (auto s = inner("log("); !s.empty()) {
    t.kind = TermKind::kLog;
    t.input = std::string(s);
  } else if (auto s2 = inner("sin("); !s2.empty()) {
    t.kind = TermKind::kSin;
    t.input = std::string(s2);
  } else if (auto s3 = inner("cos("); !s3.empty()) {
    t.kind = TermKind::kCos;
    t.input = std::string(s3);
  } else if (auto s4 = inner("exp(-"); !s4.empty()) {
    const auto slash = s4.rfind('/');
    if (slash == std::string_view::npos) throw bad("expected exp(-x/a)");
    t.kind = TermKind::kExpDecay;
    t.input = std::string(s4.substr(0, slash));
    t.a = ParseNumber(s4.substr(slash + 1), name);
    if (!(t.a > 0)) throw bad("decay length must be > 0");
  } else if (auto s5 = inner("in("); !s5.empty()) {
    const auto c1 = s5.find(',');
    const auto c2 = s5.rfind(',');
    if (c1 == std::string_view::npos || c1 == c2)
      throw bad("expected in(x,a,b)");
    t.kind = TermKind::kWindow;
    t.input = std::string(s5.substr(0, c1));
    t.a = ParseNumber(s5.substr(c1 + 1, c2 - c1 - 1), name);
    t.b = ParseNumber(s5.substr(c2 + 1), name);
    if (!(t.a < t.b)) throw bad("window start must be below its end");
  } else if (auto s6 = inner("hinge("); !s6.empty()) {
    const auto comma = s6.rfind(',');
    if (comma == std::string_view::npos) throw bad("expected hinge(x,a)");
    t.kind = TermKind::kHinge;
    t.input = std::string(s6.substr(0, comma));
    t.a = ParseNumber(s6.substr(comma + 1), name);
  } else if (auto s7 = inner("sind("); !s7.empty()) {
    t.kind = TermKind::kSinDeg;
    t.input = std::string(s7);
  } else if (auto s8 = inner("cosd("); !s8.empty()) {
    t.kind = TermKind::kCosDeg;
    t.input = std::string(s8);
  } else if (auto s9 = inner("onset("); !s9.empty()) {
    const auto c1 = s9.find(',');
    if (c1 == std::string_view::npos)
      throw bad("expected onset(x,a) or onset(x,a,b)");
    const auto c2 = s9.find(',', c1 + 1);
    t.kind = TermKind::kOnsetDecay;
    t.input = std::string(s9.substr(0, c1));
    if (c2 == std::string_view::npos) {
      t.a = ParseNumber(s9.substr(c1 + 1), name);
      t.b = 1.0;
    } else {
      t.a = ParseNumber(s9.substr(c1 + 1, c2 - c1 - 1), name);
      t.b = ParseNumber(s9.substr(c2 + 1), name);
    }
    if (!(t.a > 0)) throw bad("decay time must be > 0");
  } else if (const auto caret = name.find('^');
             caret != std::string_view::npos) {
    t.kind = TermKind::kPower;
    t.input = std::string(name.substr(0, caret));
    t.a = ParseNumber(name.substr(caret + 1), name);
  } else {
    t.kind = TermKind::kLinear;
    t.input = std::string(name);
  }
  if (t.input.empty()) throw bad("no input column");
  for (char c : t.input) {
    // '*' names a product column x*y (an interaction found by diagnosis;
    // the caller provides the column, BuildDesign reads it by name).
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '*'))
      throw bad("input '" + t.input + "' is not a column name");
  }
  return t;
}

double Term::Eval(double x) const {
  switch (kind) {
    case TermKind::kIntercept:
      return 1.0;
    case TermKind::kLinear:
      return x;
    case TermKind::kPower:
      return std::pow(x, a);
    case TermKind::kLog:
      return std::log(x);
    case TermKind::kSin:
      return std::sin(EndsWith(input, "_deg") ? x * M_PI / 180.0 : x);
    case TermKind::kCos:
      return std::cos(EndsWith(input, "_deg") ? x * M_PI / 180.0 : x);
    case TermKind::kExpDecay:
      return std::exp(-x / a);
    case TermKind::kWindow:
      return (x >= a && x < b) ? 1.0 : 0.0;
    case TermKind::kHinge:
      return x > a ? x - a : 0.0;
    case TermKind::kSinDeg:
      return std::sin(x * M_PI / 180.0);
    case TermKind::kCosDeg:
      return std::cos(x * M_PI / 180.0);
    case TermKind::kOnsetDecay:
      return 0.0;  // steady sliding: the transient has decayed
  }
  return 0.0;
}

double Term::Eval(double x, double since_onset_s) const {
  if (kind != TermKind::kOnsetDecay) return Eval(x);
  if (!(since_onset_s < std::numeric_limits<double>::infinity())) return 0.0;
  const double weight = b == 1.0 ? x : (b == 0.0 ? 1.0 : std::pow(x, b));
  return weight * std::exp(-std::max(0.0, since_onset_s) / a);
}

std::vector<double> CalcTimeSinceSlipOnset(const StrokeData& data) {
  const std::size_t n = data.size();
  std::vector<double> s(n, std::numeric_limits<double>::infinity());
  if (data.slip.size() != n) return s;
  const bool have_stroke = data.stroke.size() == n;
  double onset_t = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    if (data.slip[i] != 1) continue;
    const bool starts = i == 0 || data.slip[i - 1] != 1 ||
                        (have_stroke && data.stroke[i] != data.stroke[i - 1]);
    if (starts) onset_t = data.t_s[i];
    s[i] = data.t_s[i] - onset_t;
  }
  return s;
}

Eigen::MatrixXd BuildDesign(const StrokeData& data,
                            const std::vector<Term>& terms,
                            const std::vector<std::size_t>& rows) {
  Eigen::MatrixXd X(rows.size(), terms.size());
  std::vector<double> since_onset;
  for (const Term& term : terms) {
    if (term.NeedsSlipOnset()) {
      since_onset = CalcTimeSinceSlipOnset(data);
      break;
    }
  }
  for (std::size_t k = 0; k < terms.size(); ++k) {
    const Term& term = terms[k];
    if (term.kind == TermKind::kIntercept) {
      X.col(k).setOnes();
      continue;
    }
    const std::vector<double>* col = data.Column(term.input);
    if (!col)
      throw std::invalid_argument("term '" + term.Name() + "': no column '" +
                                  term.input + "' in the data");
    if (term.NeedsSlipOnset()) {
      for (std::size_t r = 0; r < rows.size(); ++r)
        X(r, k) = term.Eval((*col)[rows[r]], since_onset[rows[r]]);
      continue;
    }
    for (std::size_t r = 0; r < rows.size(); ++r)
      X(r, k) = term.Eval((*col)[rows[r]]);
  }
  return X;
}

namespace {

constexpr int kMomentBlock = 4096;

// Rows [i0, i0 + len) of c columns, shifted by `shift`; their sums go to
// sum[c] and the lower triangle of their Gram matrix to gram[c*c]
// (row-major, u >= w).
struct MomentBlock {
  const double* const* col;
  const double* shift;
  int c, i0, len;
  double* sum;
  double* gram;
};

// Each of kLanes rows goes to its own accumulator so the loop vectorises
// without reassociating sums.
template <int C>
inline __attribute__((always_inline)) void ShiftedMomentsKernel(
    const MomentBlock& b) {
  constexpr int kLanes = 4;
  constexpr int kPairs = C * (C + 1) / 2;
  double acc[kPairs][kLanes] = {};
  double s[C][kLanes] = {};
  int i = b.i0;
  const int end = b.i0 + b.len;
  for (; i + kLanes <= end; i += kLanes) {
    double x[C][kLanes];
    for (int u = 0; u < C; ++u) {
      for (int l = 0; l < kLanes; ++l) {
        x[u][l] = b.col[u][i + l] - b.shift[u];
        s[u][l] += x[u][l];
      }
    }
    int k = 0;
    for (int u = 0; u < C; ++u) {
      for (int w = 0; w <= u; ++w, ++k) {
        for (int l = 0; l < kLanes; ++l) acc[k][l] += x[u][l] * x[w][l];
      }
    }
  }
  for (; i < end; ++i) {
    double x[C];
    for (int u = 0; u < C; ++u) x[u] = b.col[u][i] - b.shift[u];
    int k = 0;
    for (int u = 0; u < C; ++u) {
      s[u][0] += x[u];
      for (int w = 0; w <= u; ++w, ++k) acc[k][0] += x[u] * x[w];
    }
  }
  int k = 0;
  for (int u = 0; u < C; ++u) {
    b.sum[u] = 0.0;
    for (int l = 0; l < kLanes; ++l) b.sum[u] += s[u][l];
    for (int w = 0; w <= u; ++w, ++k) {
      b.gram[u * C + w] = 0.0;
      for (int l = 0; l < kLanes; ++l) b.gram[u * C + w] += acc[k][l];
    }
  }
}

// Any column count (the designs diagnosis builds can be wide).
void ShiftedMomentsGeneric(const MomentBlock& b) {
  Eigen::MatrixXd B(b.len, b.c);
  for (int u = 0; u < b.c; ++u) {
    B.col(u) =
        Eigen::Map<const Eigen::ArrayXd>(b.col[u] + b.i0, b.len) - b.shift[u];
    b.sum[u] = B.col(u).sum();
  }
  const Eigen::MatrixXd G = B.transpose() * B;
  for (int u = 0; u < b.c; ++u) {
    for (int w = 0; w <= u; ++w) b.gram[u * b.c + w] = G(u, w);
  }
}

// Column count -> kernel; always inlined, so each caller below compiles
// the kernels for its own instruction set.
inline __attribute__((always_inline)) void DispatchShiftedMoments(
    const MomentBlock& b) {
  switch (b.c) {
    case 1:
      return ShiftedMomentsKernel<1>(b);
    case 2:
      return ShiftedMomentsKernel<2>(b);
    case 3:
      return ShiftedMomentsKernel<3>(b);
    case 4:
      return ShiftedMomentsKernel<4>(b);
    case 5:
      return ShiftedMomentsKernel<5>(b);
    default:
      return ShiftedMomentsGeneric(b);
  }
}

void ShiftedMomentsBaseline(const MomentBlock& b) { DispatchShiftedMoments(b); }

#if defined(__GNUC__) && (defined(__x86_64__) || defined(__i386__))
// The same kernels compiled for AVX2 + FMA (4 doubles per instruction
// instead of SSE2's 2), chosen at run time when the CPU has them.
__attribute__((target("avx2,fma"))) void ShiftedMomentsAvx2(
    const MomentBlock& b) {
  DispatchShiftedMoments(b);
}
#endif

void AccumulateShiftedMoments(const MomentBlock& b, bool avx2) {
#if defined(__GNUC__) && (defined(__x86_64__) || defined(__i386__))
  if (avx2) return ShiftedMomentsAvx2(b);
#endif
  ShiftedMomentsBaseline(b);
}

}  // namespace

bool OlsUsesAvx2(const OlsOptions& options) {
  return options.allow_avx2 && CpuSimdLevel() >= SimdLevel::kAvx2;
}

OlsResult FitOls(const Eigen::Ref<const Eigen::MatrixXd>& X,
                 const Eigen::Ref<const Eigen::VectorXd>& y,
                 const OlsOptions& options) {
  OlsResult r;
  const int n = static_cast<int>(X.rows());
  const int p = static_cast<int>(X.cols());
  r.samples = n;
  r.beta = Eigen::VectorXd::Zero(p);
  r.std_err = Eigen::VectorXd::Zero(p);
  r.P_beta = Eigen::MatrixXd::Zero(p, p);
  r.identified.assign(p, false);
  if (n < p + 2 || n < 3) {
    r.status = FitStatus::kTooFewSamples;
    r.why = std::to_string(n) + " samples for " + std::to_string(p) +
            " terms (need at least terms + 2)";
    return r;
  }
  // One pass over [X y] (memory-bound at 1e6 rows, so every extra pass
  // costs as much as the arithmetic): sums and Gram matrix of the data
  // shifted by the first block's mean, accumulated block by block (see
  // AccumulateShiftedMoments). The shifted-data algorithm keeps the
  // cancellation of the final centring small. A column of ones is not read
  // by that pass (its shifted values are all 0) once a check has seen it is
  // all ones.
  const int first = std::min(n, kMomentBlock);
  Eigen::RowVectorXd shift(p + 1);
  shift.head(p) = X.topRows(first).colwise().mean();
  shift(p) = y.head(first).mean();
  std::vector<bool> all_ones(p, false);
  std::vector<const double*> columns;
  std::vector<int> column_index;
  for (int k = 0; k <= p; ++k) {
    if (k < p && shift(k) == 1.0 &&
        std::all_of(X.col(k).data(), X.col(k).data() + n, [](double x) {
          return x == 1.0;
        })) {
      all_ones[k] = true;  // shifted values all exactly 0
      continue;
    }
    columns.push_back(k < p ? X.col(k).data() : y.data());
    column_index.push_back(k);
  }
  const int c = static_cast<int>(columns.size());
  const bool avx2 = OlsUsesAvx2(options);
  std::vector<double> column_shift(c);
  for (int j = 0; j < c; ++j) column_shift[j] = shift(column_index[j]);
  std::vector<double> block_sum(c), block_gram(c * c);
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(p + 1);
  Eigen::MatrixXd S = Eigen::MatrixXd::Zero(p + 1, p + 1);
  for (int i0 = 0; i0 < n; i0 += kMomentBlock) {
    const int len = std::min(kMomentBlock, n - i0);
    AccumulateShiftedMoments(MomentBlock{columns.data(),
                                         column_shift.data(),
                                         c,
                                         i0,
                                         len,
                                         block_sum.data(),
                                         block_gram.data()},
                             avx2);
    for (int u = 0; u < c; ++u) {
      sum(column_index[u]) += block_sum[u];
      for (int w = 0; w <= u; ++w)
        S(column_index[u], column_index[w]) += block_gram[u * c + w];
    }
  }
  S = S.selfadjointView<Eigen::Lower>();
  if (!S.allFinite() || !sum.allFinite()) {
    // The first column (y last) whose sum or sum of squares is not finite;
    // a cross moment alone cannot overflow when both squares are finite.
    r.nonfinite_column = p;
    for (int k = 0; k <= p; ++k) {
      if (!std::isfinite(sum(k)) || !std::isfinite(S(k, k))) {
        r.nonfinite_column = k;
        break;
      }
    }
    r.status = FitStatus::kFailed;
    r.why = (r.nonfinite_column < p
                 ? "column " + std::to_string(r.nonfinite_column) +
                       " of the design matrix"
                 : std::string("the response")) +
            " has values that are not finite or too large to sum (their "
            "squares overflow)";
    return r;
  }
  int intercept = -1;
  for (int k = 0; k < p; ++k) {
    if (all_ones[k]) {
      intercept = k;
      break;
    }
  }
  // Second moments about c: centred (c = mean) with an intercept, raw
  // (c = 0) without. With d = mean - shift:
  //   sum (u - mean_u)(w - mean_w) = S_uw - n d_u d_w,
  //   sum u w = S_uw + a_u s_w + a_w s_u + n a_u a_w   (a = shift, s = sum).
  const Eigen::VectorXd d = sum / n;
  const Eigen::VectorXd a = shift.transpose();
  const Eigen::MatrixXd M =
      intercept >= 0
          ? Eigen::MatrixXd(S - n * d * d.transpose())
          : Eigen::MatrixXd(S + a * sum.transpose() + sum * a.transpose() +
                            n * a * a.transpose());
  const Eigen::RowVectorXd mean = (a + d).head(p).transpose();
  Eigen::VectorXd scale(p);
  for (int k = 0; k < p; ++k)
    scale(k) = k == intercept ? 1.0 : std::sqrt(std::max(0.0, M(k, k)) / n);
  // Gram matrix of the standardised non-intercept columns.
  std::vector<int> cols;
  for (int k = 0; k < p; ++k) {
    if (k == intercept) continue;
    const double rel = scale(k) / (std::fabs(mean(k)) + scale(k) + 1e-300);
    if (scale(k) > 0 && rel > 1e-12) cols.push_back(k);
  }
  const int q = static_cast<int>(cols.size());
  Eigen::MatrixXd G(q, q);
  Eigen::VectorXd g(q);
  for (int i = 0; i < q; ++i) {
    g(i) = M(cols[i], p) / scale(cols[i]);
    for (int j = 0; j < q; ++j)
      G(i, j) = M(cols[i], cols[j]) / (scale(cols[i]) * scale(cols[j]));
  }
  const double ybar = intercept >= 0 ? a(p) + d(p) : 0.0;
  // Rank check: pivoted QR of the Gram matrix (well scaled: diag = n).
  std::vector<int> keep;
  if (q > 0) {
    Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(G / n);
    qr.setThreshold(1e-10);
    const int rank = static_cast<int>(qr.rank());
    for (int j = 0; j < rank; ++j)
      keep.push_back(qr.colsPermutation().indices()(j));
    std::sort(keep.begin(), keep.end());
  }
  const int m = static_cast<int>(keep.size());
  Eigen::MatrixXd Gk(m, m);
  Eigen::VectorXd gk(m);
  for (int a = 0; a < m; ++a) {
    gk(a) = g(keep[a]);
    for (int b = 0; b < m; ++b) Gk(a, b) = G(keep[a], keep[b]);
  }
  Eigen::LDLT<Eigen::MatrixXd> ldlt(Gk);
  if (m > 0 && ldlt.info() != Eigen::Success) {
    r.status = FitStatus::kFailed;
    r.why = "normal equations could not be factorised";
    return r;
  }
  const Eigen::VectorXd bz =
      m > 0 ? Eigen::VectorXd(ldlt.solve(gk)) : Eigen::VectorXd();
  const Eigen::MatrixXd Ginv =
      m > 0 ? Eigen::MatrixXd(ldlt.solve(Eigen::MatrixXd::Identity(m, m)))
            : Eigen::MatrixXd();
  // Back to the original scale.
  double intercept_beta = ybar;
  for (int a = 0; a < m; ++a) {
    const int k = cols[keep[a]];
    r.beta(k) = bz(a) / scale(k);
    r.identified[k] = true;
    if (intercept >= 0) intercept_beta -= r.beta(k) * mean(k);
  }
  if (intercept >= 0) {
    r.beta(intercept) = intercept_beta;
    r.identified[intercept] = true;
  }
  const int p_eff = m + (intercept >= 0 ? 1 : 0);
  double rss = 0.0;
  if (options.residuals) {
    r.residuals.noalias() = y - X * r.beta;
    rss = r.residuals.squaredNorm();
  } else {
    // From the moments: rss = M_yy - g' G^-1 g (the normal equations'
    // residual sum of squares in the standardised coordinates).
    rss = std::max(0.0, M(p, p) - (m > 0 ? gk.dot(bz) : 0.0));
  }
  const double tss = std::max(0.0, M(p, p));
  r.dof = n - p_eff;
  const double s2 = rss / std::max(1, r.dof);
  r.sigma_eps = std::sqrt(s2);
  r.r2 = tss > 0 ? 1.0 - rss / tss : 0.0;
  if (m > 0 && intercept >= 0 && rss > 0) {
    r.f_stat = ((tss - rss) / m) / s2;
    r.p_value = FUpperP(r.f_stat, m, r.dof);
  } else if (m > 0 && intercept >= 0) {
    r.f_stat = std::numeric_limits<double>::infinity();
    r.p_value = 0.0;
  }
  // Covariance: slopes from Ginv, intercept from the delta method.
  for (int a = 0; a < m; ++a) {
    for (int b = 0; b < m; ++b) {
      const int ka = cols[keep[a]], kb = cols[keep[b]];
      r.P_beta(ka, kb) = s2 * Ginv(a, b) / (scale(ka) * scale(kb));
    }
  }
  if (intercept >= 0) {
    double var0 = s2 / n;
    for (int a = 0; a < m; ++a) {
      const int ka = cols[keep[a]];
      double cov = 0.0;
      for (int b = 0; b < m; ++b) {
        const int kb = cols[keep[b]];
        cov -= r.P_beta(ka, kb) * mean(kb);
      }
      r.P_beta(intercept, ka) = r.P_beta(ka, intercept) = cov;
      var0 -= cov * mean(ka);
    }
    r.P_beta(intercept, intercept) = var0;
  }
  r.std_err = r.P_beta.diagonal().cwiseMax(0.0).cwiseSqrt();
  if (p_eff < p) {
    r.status = FitStatus::kPartial;
    r.why = std::to_string(p - p_eff) +
            " term(s) not identified (constant or collinear input)";
  } else {
    r.status = FitStatus::kOk;
  }
  return r;
}

}  // namespace frictiond

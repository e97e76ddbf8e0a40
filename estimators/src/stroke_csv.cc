#include "frictiond/estimators/stroke_csv.h"

#include <charconv>
#include <cmath>
#include <limits>
#include <vector>

#include "frictiond/estimators/number_text.h"
#include "frictiond/estimators/preprocessing.h"

namespace frictiond {

StrokeCsvError::StrokeCsvError(std::size_t line,
                               std::string field,
                               const std::string& message,
                               bool too_large)
    : FieldError(
          std::move(field),
          line > 0 ? "line " + std::to_string(line) + ": " + message : message),
      line_(line),
      too_large_(too_large) {}

namespace {

enum class Role { kTime, kFn, kFt, kV, kSlip, kStroke, kCovariate };

struct ColumnSpec {
  std::string name;
  Role role;
  std::size_t covariate_index = 0;
};

std::string_view Trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t'))
    s.remove_prefix(1);
  while (!s.empty() &&
         (s.back() == ' ' || s.back() == '\t' || s.back() == '\r'))
    s.remove_suffix(1);
  return s;
}

bool ValidName(std::string_view s) {
  if (s.empty() || s.size() > 64) return false;
  auto alpha = [](char c) {
    return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || c == '_';
  };
  if (!alpha(s[0])) return false;
  for (char c : s) {
    if (!(alpha(c) || (c >= '0' && c <= '9'))) return false;
  }
  return true;
}

// Outside text quoted in a message: at most 40 bytes, control characters
// shown as '?' (a NUL would end the message at what(); the server's
// ShownText, text.h, applies the same rule and also replaces invalid UTF-8).
std::string Quote(std::string_view s) {
  std::string out(s.substr(0, 40));
  for (char& c : out) {
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7F) c = '?';
  }
  if (s.size() > 40) out += "...";
  return "'" + out + "'";
}

}  // namespace

StrokeData ParseStrokeCsv(std::string_view text,
                          const StrokeCsvOptions& options) {
  StrokeData data;
  std::vector<ColumnSpec> columns;
  bool have[4] = {false, false, false, false};
  bool have_slip = false;
  bool have_stroke = false;
  std::size_t line_no = 0;
  std::size_t pos = 0;
  bool header_done = false;
  std::vector<std::string_view> cells;
  double last_t = -std::numeric_limits<double>::infinity();

  if (Trim(text).empty())
    throw StrokeCsvError(
        0, "body", "body: empty (expected a stroke CSV with a header row)");
  // Rough sample count to reserve (one row per ~32 bytes).
  const std::size_t guess =
      std::min<std::size_t>(text.size() / 24 + 1, options.max_samples);

  while (pos < text.size()) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    std::string_view line = text.substr(pos, end - pos);
    pos = end + 1;
    ++line_no;
    std::string_view t = Trim(line);
    if (t.empty() || t.front() == '#') continue;

    cells.clear();
    std::size_t start = 0;
    while (true) {
      std::size_t comma = t.find(',', start);
      if (comma == std::string_view::npos) {
        cells.push_back(Trim(t.substr(start)));
        break;
      }
      cells.push_back(Trim(t.substr(start, comma - start)));
      start = comma + 1;
    }

    if (!header_done) {
      header_done = true;
      if (cells.size() > options.max_columns) {
        throw StrokeCsvError(line_no,
                             "header",
                             "header: " + std::to_string(cells.size()) +
                                 " columns (at most " +
                                 std::to_string(options.max_columns) + ")");
      }
      for (std::size_t c = 0; c < cells.size(); ++c) {
        std::string_view name = cells[c];
        if (!ValidName(name)) {
          throw StrokeCsvError(
              line_no,
              "header",
              "header: column " + std::to_string(c + 1) + " name " +
                  Quote(name) +
                  " is not a valid column name "
                  "([A-Za-z_][A-Za-z0-9_]*, at most 64 characters)");
        }
        if (name == "intercept") {
          // The model's constant term has this name in every coefficient
          // map and term list; a covariate of that name could only enter
          // as `fn_n*intercept` (outside attack run).
          throw StrokeCsvError(line_no,
                               "header",
                               "header: column 'intercept' is reserved for "
                               "the model's constant term (rename it)");
        }
        for (const std::string& derived : DerivedFeatureNames()) {
          if (name == derived) {
            // Computed from the required columns (CONTRACT.md); a user
            // column of that name lost its values to the derived ones
            // without a word, and a diagnosis `cause` naming it would be
            // ambiguous.
            std::string reserved;  // the list itself, not a copy of it
            for (const std::string& d : DerivedFeatureNames())
              reserved += (reserved.empty() ? "" : ", ") + d;
            throw StrokeCsvError(
                line_no,
                std::string(name),
                "header: column " + Quote(name) +
                    " is a derived feature the library computes from "
                    "t_s, fn_n and v_mm_s (" +
                    reserved + " are reserved; rename it)");
          }
        }
        for (const auto& prev : columns) {
          if (prev.name == name) {
            throw StrokeCsvError(
                line_no,
                std::string(name),
                "header: column " + Quote(name) + " appears twice");
          }
        }
        ColumnSpec spec{std::string(name), Role::kCovariate};
        if (name == "t_s")
          spec.role = Role::kTime, have[0] = true;
        else if (name == "fn_n")
          spec.role = Role::kFn, have[1] = true;
        else if (name == "ft_n")
          spec.role = Role::kFt, have[2] = true;
        else if (name == "v_mm_s")
          spec.role = Role::kV, have[3] = true;
        else if (name == "slip")
          spec.role = Role::kSlip, have_slip = true;
        else if (name == "stroke")
          spec.role = Role::kStroke, have_stroke = true;
        else {
          spec.covariate_index = data.covariate_names.size();
          data.covariate_names.push_back(spec.name);
          data.covariates.emplace_back();
          data.covariates.back().reserve(guess);
        }
        columns.push_back(std::move(spec));
      }
      static const char* kRequired[4] = {"t_s", "fn_n", "ft_n", "v_mm_s"};
      for (int r = 0; r < 4; ++r) {
        if (!have[r]) {
          throw StrokeCsvError(
              line_no,
              kRequired[r],
              std::string("header: missing required column '") + kRequired[r] +
                  "' (required: t_s, fn_n, ft_n, v_mm_s)");
        }
      }
      data.Reserve(guess);
      if (have_slip) data.slip.reserve(guess);
      if (have_stroke) data.stroke.reserve(guess);
      continue;
    }

    if (cells.size() != columns.size()) {
      throw StrokeCsvError(line_no,
                           "row",
                           "row has " + std::to_string(cells.size()) +
                               " cells, header has " +
                               std::to_string(columns.size()));
    }
    if (data.size() >= options.max_samples) {
      throw StrokeCsvError(line_no,
                           "body",
                           "more than " + std::to_string(options.max_samples) +
                               " samples (split the upload)",
                           /*too_large=*/true);
    }
    for (std::size_t c = 0; c < cells.size(); ++c) {
      const ColumnSpec& spec = columns[c];
      std::string_view cell = cells[c];
      double x = 0;
      const char* b = cell.data();
      const char* e = cell.data() + cell.size();
      if (!cell.empty() && *b == '+') ++b;
      auto [ptr, ec] = std::from_chars(b, e, x);
      if (cell.empty() || ec != std::errc() || ptr != e) {
        throw StrokeCsvError(
            line_no,
            spec.name,
            spec.name + " = " + Quote(cell) + " (not a number)");
      }
      if (!std::isfinite(x)) {
        throw StrokeCsvError(
            line_no,
            spec.name,
            spec.name + " = " + Quote(cell) + " (must be finite)");
      }
      switch (spec.role) {
        case Role::kTime:
          data.t_s.push_back(x);
          break;
        case Role::kFn:
          data.fn_n.push_back(x);
          break;
        case Role::kFt:
          data.ft_n.push_back(x);
          break;
        case Role::kV:
          data.v_mm_s.push_back(x);
          break;
        case Role::kSlip:
          if (!(x == 0 || x == 1))
            throw StrokeCsvError(
                line_no,
                spec.name,
                "slip = " + NumberText(x) + " (must be 0 or 1)");
          data.slip.push_back(static_cast<int>(x));
          break;
        case Role::kStroke:
          if (!(x == std::floor(x)) || std::fabs(x) > 2e9) {
            throw StrokeCsvError(
                line_no,
                spec.name,
                "stroke = " + NumberText(x) + " (must be an integer)");
          }
          data.stroke.push_back(static_cast<int>(x));
          break;
        case Role::kCovariate:
          data.covariates[spec.covariate_index].push_back(x);
          break;
      }
    }
    // The row's required values: the one per-sample rule (stroke_data.h).
    if (auto bad = CheckSample(data.t_s.back(),
                               data.fn_n.back(),
                               data.ft_n.back(),
                               data.v_mm_s.back(),
                               last_t)) {
      throw StrokeCsvError(
          line_no,
          bad->field,
          bad->field + " = " + NumberText(bad->value) + " (" +
              (bad->bound.empty() ? bad->rule : "must be " + bad->bound) + ")");
    }
    last_t = data.t_s.back();
  }
  if (!header_done)
    throw StrokeCsvError(
        0, "body", "body: no header row (only comments or blank lines)");
  if (data.empty())
    throw StrokeCsvError(line_no, "body", "body: header but no samples");
  return data;
}

std::string FormatStrokeCsv(const StrokeData& data) {
  std::string out = "t_s,fn_n,ft_n,v_mm_s";
  const bool slip = data.slip.size() == data.size();
  const bool stroke = data.stroke.size() == data.size();
  if (slip) out += ",slip";
  if (stroke) out += ",stroke";
  for (const auto& n : data.covariate_names) out += "," + n;
  out += '\n';
  out.reserve(out.size() + data.size() * (4 + data.covariates.size()) * 12);
  char buf[40];
  auto put = [&](double x) {
    auto [p, ec] = std::to_chars(buf, buf + sizeof buf, x);
    (void)ec;
    out.append(buf, p);
  };
  for (std::size_t i = 0; i < data.size(); ++i) {
    put(data.t_s[i]);
    out += ',';
    put(data.fn_n[i]);
    out += ',';
    put(data.ft_n[i]);
    out += ',';
    put(data.v_mm_s[i]);
    if (slip) out += data.slip[i] ? ",1" : ",0";
    if (stroke) out += "," + std::to_string(data.stroke[i]);
    for (const auto& col : data.covariates) {
      out += ',';
      put(col[i]);
    }
    out += '\n';
  }
  return out;
}

}  // namespace frictiond

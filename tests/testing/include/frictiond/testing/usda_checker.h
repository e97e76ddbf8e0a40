#pragma once
// A checker for the subset of the usda 1.0 text grammar that frictiond
// emits, written from the USD file-format documentation (not from our
// emitter): the "#usda 1.0" header line, optional layer metadata "( ... )",
// prims "def [Type] "name" ( metadata ) { ... }" nested freely, typed
// attributes "[custom] type[[]] ns:name = value" with numbers, quoted
// strings and [ ] arrays, list-edited metadata ("prepend apiSchemas = [..]"),
// '#' line comments. Anything else is a syntax error with a line number.
#include <cctype>
#include <cstdlib>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace frictiond::usda {

struct Attribute {
  std::string type;  // "float", "double", ...
  bool array = false;
  bool custom = false;
  std::vector<std::string> values;  // numbers as text, strings unquoted
};

struct Prim {
  std::string specifier;  // "def"
  std::string type;       // "Material" (may be empty)
  std::string name;
  std::map<std::string, std::vector<std::string>> metadata;  // key -> values
  std::map<std::string, Attribute> attributes;
  std::vector<Prim> children;
};

struct Layer {
  std::map<std::string, std::vector<std::string>> metadata;
  std::vector<Prim> prims;
};

class SyntaxError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

namespace internal {

enum class Kind { kIdent, kNumber, kString, kPunct, kEnd };
struct Token {
  Kind kind;
  std::string text;
  int line;
};

inline std::vector<Token> Tokenize(const std::string& s) {
  const std::string header = "#usda 1.0";
  if (s.compare(0, header.size(), header) != 0 ||
      (s.size() > header.size() && s[header.size()] != '\n'))
    throw SyntaxError("line 1: expected the header '#usda 1.0'");
  std::vector<Token> out;
  int line = 1;
  std::size_t i = header.size();
  auto fail = [&](const std::string& why) {
    throw SyntaxError("line " + std::to_string(line) + ": " + why);
  };
  while (i < s.size()) {
    const char c = s[i];
    if (c == '\n') {
      ++line;
      ++i;
    } else if (c == ' ' || c == '\t' || c == '\r') {
      ++i;
    } else if (c == '#') {
      while (i < s.size() && s[i] != '\n') ++i;
    } else if (std::isalpha(static_cast<unsigned char>(c)) || c == '_') {
      std::size_t j = i;
      while (j < s.size() && (std::isalnum(static_cast<unsigned char>(s[j])) ||
                              s[j] == '_' || s[j] == ':'))
        ++j;
      if (s[j - 1] == ':') fail("identifier ends in ':'");
      out.push_back({Kind::kIdent, s.substr(i, j - i), line});
      i = j;
    } else if (std::isdigit(static_cast<unsigned char>(c)) || c == '-' ||
               c == '.') {
      const char* begin = s.c_str() + i;
      char* end = nullptr;
      std::strtod(begin, &end);
      if (end == begin) fail("bad number");
      const std::size_t n = static_cast<std::size_t>(end - begin);
      out.push_back({Kind::kNumber, s.substr(i, n), line});
      i += n;
    } else if (c == '"') {
      std::string text;
      ++i;
      for (;; ++i) {
        if (i >= s.size() || s[i] == '\n') fail("unterminated string");
        if (s[i] == '\\') {
          if (i + 1 >= s.size()) fail("unterminated string");
          text += s[++i];
        } else if (s[i] == '"') {
          ++i;
          break;
        } else {
          text += s[i];
        }
      }
      out.push_back({Kind::kString, text, line});
    } else if (std::string("(){}[]=,").find(c) != std::string::npos) {
      out.push_back({Kind::kPunct, std::string(1, c), line});
      ++i;
    } else {
      fail(std::string("unexpected character '") + c + "'");
    }
  }
  out.push_back({Kind::kEnd, "", line});
  return out;
}

class Parser {
 public:
  explicit Parser(std::vector<Token> t) : t_(std::move(t)) {}

  Layer ParseLayer() {
    Layer layer;
    if (Is("(")) layer.metadata = ParseMetadata();
    while (!At(Kind::kEnd)) layer.prims.push_back(ParsePrim());
    return layer;
  }

 private:
  const Token& Peek() const { return t_[pos_]; }
  bool At(Kind k) const { return Peek().kind == k; }
  bool Is(const std::string& punct) const {
    return Peek().kind == Kind::kPunct && Peek().text == punct;
  }
  [[noreturn]] void Fail(const std::string& why) const {
    throw SyntaxError("line " + std::to_string(Peek().line) + ": " + why +
                      " (at '" + Peek().text + "')");
  }
  Token Take(Kind k, const std::string& what) {
    if (!At(k)) Fail("expected " + what);
    return t_[pos_++];
  }
  void Expect(const std::string& punct) {
    if (!Is(punct)) Fail("expected '" + punct + "'");
    ++pos_;
  }

  // value := NUMBER | STRING | IDENT (token literal) | '[' values ']'
  std::vector<std::string> ParseValue(bool* was_array = nullptr,
                                      Kind* kind = nullptr) {
    std::vector<std::string> out;
    if (Is("[")) {
      ++pos_;
      if (was_array) *was_array = true;
      Kind element = Kind::kEnd;
      while (!Is("]")) {
        if (!At(Kind::kNumber) && !At(Kind::kString))
          Fail("expected a number or string in an array");
        if (element != Kind::kEnd && Peek().kind != element)
          Fail("mixed element kinds in an array");
        element = Peek().kind;
        out.push_back(t_[pos_++].text);
        if (!Is("]")) Expect(",");
      }
      ++pos_;
      if (kind) *kind = element;
      return out;
    }
    if (was_array) *was_array = false;
    if (!At(Kind::kNumber) && !At(Kind::kString)) Fail("expected a value");
    if (kind) *kind = Peek().kind;
    out.push_back(t_[pos_++].text);
    return out;
  }

  std::map<std::string, std::vector<std::string>> ParseMetadata() {
    std::map<std::string, std::vector<std::string>> out;
    Expect("(");
    while (!Is(")")) {
      std::string key = Take(Kind::kIdent, "a metadata key").text;
      if (key == "prepend" || key == "append" || key == "delete")
        key = Take(Kind::kIdent, "a list-edited metadata key").text;
      Expect("=");
      if (out.count(key)) Fail("duplicate metadata '" + key + "'");
      out[key] = ParseValue();
    }
    Expect(")");
    return out;
  }

  Prim ParsePrim() {
    Prim p;
    p.specifier = Take(Kind::kIdent, "a prim specifier").text;
    if (p.specifier != "def" && p.specifier != "over" && p.specifier != "class")
      Fail("expected def, over or class");
    if (At(Kind::kIdent)) p.type = t_[pos_++].text;
    p.name = Take(Kind::kString, "a quoted prim name").text;
    if (p.name.empty() ||
        !(std::isalpha(static_cast<unsigned char>(p.name[0])) ||
          p.name[0] == '_'))
      Fail("prim name '" + p.name + "' is not an identifier");
    for (char c : p.name) {
      if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_')
        Fail("prim name '" + p.name + "' is not an identifier");
    }
    if (Is("(")) p.metadata = ParseMetadata();
    Expect("{");
    while (!Is("}")) {
      if (At(Kind::kEnd)) Fail("unbalanced '{'");
      const std::string& w = Peek().text;
      if (w == "def" || w == "over" || w == "class") {
        p.children.push_back(ParsePrim());
        continue;
      }
      Attribute a;
      if (w == "custom") {
        a.custom = true;
        ++pos_;
      }
      a.type = Take(Kind::kIdent, "an attribute type").text;
      static const char* kTypes[] = {
          "bool", "int", "float", "double", "string", "token"};
      bool known = false;
      for (const char* k : kTypes) known = known || a.type == k;
      if (!known) Fail("unknown attribute type '" + a.type + "'");
      if (Is("[")) {
        ++pos_;
        Expect("]");
        a.array = true;
      }
      const std::string name = Take(Kind::kIdent, "an attribute name").text;
      Expect("=");
      bool was_array = false;
      Kind kind = Kind::kEnd;
      a.values = ParseValue(&was_array, &kind);
      if (was_array != a.array)
        Fail("attribute '" + name + "': array-ness of type and value differ");
      const bool numeric = a.type != "string" && a.type != "token";
      if (!a.values.empty() && numeric != (kind == Kind::kNumber))
        Fail("attribute '" + name + "': value does not match type " + a.type);
      if (a.type == "int") {
        for (const auto& v : a.values) {
          if (v.find_first_of(".eE") != std::string::npos)
            Fail("attribute '" + name + "': int value " + v);
        }
      }
      if (p.attributes.count(name)) Fail("duplicate attribute '" + name + "'");
      p.attributes[name] = a;
    }
    Expect("}");
    return p;
  }

  std::vector<Token> t_;
  std::size_t pos_ = 0;
};

}  // namespace internal

/// Parses usda text. @throws SyntaxError with the line and the reason.
inline Layer Parse(const std::string& text) {
  return internal::Parser(internal::Tokenize(text)).ParseLayer();
}

}  // namespace frictiond::usda

#include "render/clamped_parameters.h"

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <system_error>

namespace glimmer::render {

namespace {

constexpr const char *kVersionLine = "glimmer-clamped-parameters 1";
constexpr size_t kFields = 8;

bool same_parameter(const ClampedParameterRecord &a, const ClampedParameterRecord &b) {
  return a.where == b.where && a.what == b.what && a.min_value == b.min_value && a.max_value == b.max_value;
}

// The texts' characters that would break the line format, as two-character escapes ('\0': none).
char escape_of(char c) {
  switch (c) {
    case '\\':
      return '\\';
    case '\t':
      return 't';
    case '\n':
      return 'n';
    case '\r':
      return 'r';
    default:
      return '\0';
  }
}

std::string escape(const std::string &text) {
  std::string out;
  for (const char c : text) {
    const char e = escape_of(c);
    if (e != '\0') out += '\\';
    out += e != '\0' ? e : c;
  }
  return out;
}

std::string unescape(const std::string &text) {
  std::string out;
  for (size_t i = 0; i < text.size(); ++i) {
    if (text[i] != '\\') {
      out += text[i];
      continue;
    }
    const char e = i + 1 < text.size() ? text[++i] : '\0';
    const char *const escaped = "\\\t\n\r", *const codes = "\\tnr";
    const char *at = e != '\0' ? std::strchr(codes, e) : nullptr;
    if (at == nullptr) throw std::runtime_error("unknown escape in '" + text + "'");
    out += escaped[at - codes];
  }
  return out;
}

template <typename T>
std::string number_text(T value) {
  char buf[64];
  const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, value);
  return ec == std::errc() ? std::string(buf, end) : std::string("nan");
}

template <typename T>
T parse_number(const std::string &field, const char *name) {
  T value{};
  const char *end = field.data() + field.size();
  const auto [ptr, ec] = std::from_chars(field.data(), end, value);
  if (field.empty() || ec != std::errc() || ptr != end)
    throw std::runtime_error(std::string(name) + " '" + field + "' is not a number");
  return value;
}

std::vector<std::string> split(const std::string &line, char sep) {
  std::vector<std::string> fields;
  size_t start = 0;
  for (size_t cut; (cut = line.find(sep, start)) != std::string::npos; start = cut + 1)
    fields.push_back(line.substr(start, cut - start));
  fields.push_back(line.substr(start));
  return fields;
}

ClampedParameterRecord decode_record(const std::string &line) {
  const std::vector<std::string> f = split(line, '\t');
  if (f.size() != kFields)
    throw std::runtime_error(std::to_string(f.size()) + " fields, not " + std::to_string(kFields));
  ClampedParameterRecord r;
  r.where = unescape(f[0]);
  r.what = unescape(f[1]);
  r.min_value = parse_number<float>(f[2], "min");
  r.max_value = parse_number<float>(f[3], "max");
  r.below = parse_number<uint64_t>(f[4], "below");
  r.above = parse_number<uint64_t>(f[5], "above");
  r.lowest = parse_number<float>(f[6], "lowest");
  r.highest = parse_number<float>(f[7], "highest");
  return r;
}

std::string g_text(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", x);
  return buf;
}

}  // namespace

void add_clamped_records(ClampedParameterRecords &into, const ClampedParameterRecords &from) {
  for (const ClampedParameterRecord &r : from) {
    auto it = std::find_if(into.begin(), into.end(), [&r](const auto &x) { return same_parameter(x, r); });
    if (it == into.end()) {
      into.push_back(r);
      continue;
    }
    it->below += r.below;
    it->above += r.above;
    it->lowest = std::min(it->lowest, r.lowest);
    it->highest = std::max(it->highest, r.highest);
  }
}

std::vector<std::string> clamped_parameter_warnings(const ClampedParameterRecords &records) {
  std::vector<std::string> out;
  for (const ClampedParameterRecord &c : records) {
    const std::string head = c.where + ": warning: " + c.what + ": ";
    const std::string range = " (its range is [" + g_text(c.min_value) + ", " + g_text(c.max_value) + "])";
    if (c.below > 0)
      out.push_back(head + std::to_string(c.below) +
                    " shading points had a textured value below the minimum, down to " + g_text(c.lowest) +
                    ", clamped to " + g_text(c.min_value) + range);
    if (c.above > 0)
      out.push_back(head + std::to_string(c.above) + " shading points had a textured value above the maximum, up to " +
                    g_text(c.highest) + ", clamped to " + g_text(c.max_value) + range);
  }
  return out;
}

std::string encode_clamped_records(const ClampedParameterRecords &records) {
  if (records.empty()) return "";
  std::string out = kVersionLine;
  for (const ClampedParameterRecord &r : records) {
    const std::string fields[kFields] = {escape(r.where),          escape(r.what),        number_text(r.min_value),
                                         number_text(r.max_value), number_text(r.below),  number_text(r.above),
                                         number_text(r.lowest),    number_text(r.highest)};
    for (size_t k = 0; k < kFields; ++k) {
      out += k == 0 ? '\n' : '\t';
      out += fields[k];
    }
  }
  return out;
}

ClampedParameterRecords decode_clamped_records(const std::string &text) {
  ClampedParameterRecords records;
  if (text.empty()) return records;
  const std::vector<std::string> lines = split(text, '\n');
  if (lines[0] != kVersionLine)
    throw std::runtime_error(std::string(kClampedParametersAttribute) + ": the first line is '" + lines[0] +
                             "', not '" + kVersionLine + "' (written by another version of glimmer?)");
  for (size_t k = 1; k < lines.size(); ++k) {
    try {
      records.push_back(decode_record(lines[k]));
    } catch (const std::exception &e) {
      throw std::runtime_error(std::string(kClampedParametersAttribute) + ": line " + std::to_string(k + 1) + ": " +
                               e.what());
    }
  }
  return records;
}

}  // namespace glimmer::render

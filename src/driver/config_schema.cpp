#include "driver/config_schema.h"

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <type_traits>
#include <utility>

#include "slam/common/error.h"

namespace pcr::driver {
namespace {

int LineOf(const YAML::Node& node) { return node.Mark().line >= 0 ? node.Mark().line + 1 : 0; }

// line: the key's (a key with no value has a null node whose mark is the next line's).
template <typename T>
T Convert(const YAML::Node& node, const std::string& source, int line, const std::string& what,
          const char* type_name) {
  if (!node.IsScalar())
    throw InputError(source, line, what + ": expected a " + type_name + " value");
  try {
    return node.as<T>();
  } catch (const YAML::Exception&) {
    throw InputError(source, line, what + ": '" + node.Scalar() + "' is not a valid " + type_name);
  }
}

void Assign(const ConfigSchema::FieldPtr& ptr, const YAML::Node& value, const std::string& source,
            int line, const std::string& what) {
  std::visit(
      [&](auto* field) {
        using T = std::remove_pointer_t<decltype(field)>;
        if constexpr (std::is_same_v<T, int>) {
          *field = Convert<int>(value, source, line, what, "integer");
        } else if constexpr (std::is_same_v<T, double>) {
          const double v = Convert<double>(value, source, line, what, "number");
          if (!std::isfinite(v)) throw InputError(source, line, what + ": value must be finite");
          *field = v;
        } else if constexpr (std::is_same_v<T, bool>) {
          *field = Convert<bool>(value, source, line, what, "boolean (true/false)");
        } else {
          *field = Convert<std::string>(value, source, line, what, "string");
        }
      },
      ptr);
}

// The value `field` points at.
std::variant<int, double, bool, std::string> Get(const ConfigSchema::FieldPtr& field) {
  return std::visit([](auto* p) { return std::variant<int, double, bool, std::string>(*p); },
                    field);
}

// Writes `value` (of the field's own type) through `field`.
void Put(const ConfigSchema::FieldPtr& field,
         const std::variant<int, double, bool, std::string>& value) {
  std::visit([&](auto* p) { *p = std::get<std::remove_pointer_t<decltype(p)>>(value); }, field);
}

// A section or key name: a scalar (a sequence or a map as a key is an error naming the line).
std::string NameOf(const YAML::Node& key, const std::string& source, const char* what) {
  if (!key.IsScalar())
    throw InputError(source, LineOf(key), std::string(what) + " names must be plain words");
  return key.Scalar();
}

}  // namespace

void ConfigSchema::Add(const std::string& section, const std::string& key, FieldPtr field,
                       const std::string& doc) {
  if (Find(section, key))
    throw std::logic_error("config key registered twice: " + section + "." + key);
  fields_.push_back({section, key, doc, field, Get(field), std::nullopt});
}

bool ConfigSchema::Has(const std::string& section, const std::string& key) const {
  return Find(section, key) != nullptr;
}

const ConfigSchema::Field* ConfigSchema::Find(const std::string& section,
                                              const std::string& key) const {
  for (const Field& f : fields_)
    if (f.section == section && f.key == key) return &f;
  return nullptr;
}

ConfigSchema::Field* ConfigSchema::Find(const std::string& section, const std::string& key) {
  return const_cast<Field*>(std::as_const(*this).Find(section, key));
}

void ConfigSchema::LoadFile(const std::string& path) {
  // A regular file only: a directory opens and reads as nothing (all defaults), a device or a
  // FIFO (/dev/zero) is read until memory runs out.
  std::error_code ec;
  if (std::filesystem::exists(path, ec) && !std::filesystem::is_regular_file(path, ec))
    throw InputError(path, 0,
                     std::filesystem::is_directory(path, ec)
                         ? "is a directory, not a configuration file"
                         : "is not a regular file, not a configuration file");
  std::ifstream in(path);
  if (!in) throw InputError(path, 0, "cannot open configuration file");
  std::stringstream ss;
  ss << in.rdbuf();  // an empty file sets ss's failbit: that is all defaults, not an error
  if (in.bad()) throw InputError(path, 0, "cannot read configuration file");
  LoadString(ss.str(), path);
}

void ConfigSchema::LoadString(const std::string& text, const std::string& source_name) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::ParserException& e) {
    throw InputError(source_name, e.mark.line + 1, "malformed YAML: " + e.msg);
  }
  if (root.IsNull()) return;  // empty file: all defaults
  if (!root.IsMap()) throw InputError(source_name, LineOf(root), "expected a map of sections");
  // All or nothing: a file that fails half-way leaves the configuration as it was.
  std::vector<Value> saved;
  std::vector<std::optional<Origin>> saved_origins;
  for (const Field& f : fields_) {
    saved.push_back(Get(f.ptr));
    saved_origins.push_back(f.origin);
  }
  try {
    try {
      Apply(root, source_name);
    } catch (const YAML::Exception& e) {
      throw InputError(source_name, e.mark.line >= 0 ? e.mark.line + 1 : 0, e.msg);
    }
  } catch (...) {
    for (size_t i = 0; i < fields_.size(); ++i) {
      Put(fields_[i].ptr, saved[i]);
      fields_[i].origin = saved_origins[i];
    }
    throw;
  }
}

void ConfigSchema::Apply(const YAML::Node& root, const std::string& source) {
  std::set<std::string> sections;
  for (const Field& f : fields_) sections.insert(f.section);
  // yaml-cpp keeps every pair of a map, a repeated key too: the second one would silently win.
  std::map<std::string, int> section_lines;
  for (const auto& sec : root) {
    const std::string section = NameOf(sec.first, source, "section");
    if (const auto [it, first] = section_lines.emplace(section, LineOf(sec.first)); !first)
      throw InputError(source, LineOf(sec.first),
                       "section '" + section + "' given twice (first at line " +
                           std::to_string(it->second) + ")");
    if (!sections.count(section)) {
      std::string known;
      for (const auto& s : sections) known += (known.empty() ? "" : ", ") + s;
      throw InputError(source, LineOf(sec.first),
                       "unknown section '" + section + "' (known: " + known + ")");
    }
    if (sec.second.IsNull()) continue;
    if (!sec.second.IsMap())
      throw InputError(source, LineOf(sec.second), "section '" + section + "' must be a map");
    std::map<std::string, int> key_lines;
    for (const auto& kv : sec.second) {
      const std::string key = NameOf(kv.first, source, "key");
      if (const auto [it, first] = key_lines.emplace(key, LineOf(kv.first)); !first)
        throw InputError(source, LineOf(kv.first),
                         "key '" + section + "." + key + "' given twice (first at line " +
                             std::to_string(it->second) + ")");
      Field* f = Find(section, key);
      if (!f)
        throw InputError(source, LineOf(kv.first), "unknown key '" + section + "." + key + "'");
      Assign(f->ptr, kv.second, source, LineOf(kv.first), section + "." + key);
      f->origin = Origin{source, LineOf(kv.first), section + "." + key};
    }
  }
}

void ConfigSchema::Set(const std::string& assignment, const std::string& source_name) {
  const auto eq = assignment.find('=');
  const auto dot = assignment.find('.');
  if (eq == std::string::npos || dot == std::string::npos || dot > eq)
    throw InputError(source_name, 0, "override '" + assignment + "' is not section.key=value");
  const std::string section = assignment.substr(0, dot);
  const std::string key = assignment.substr(dot + 1, eq - dot - 1);
  Field* f = Find(section, key);
  if (!f) throw InputError(source_name, 0, "unknown key '" + section + "." + key + "'");
  const std::string what = section + "." + key;
  YAML::Node value;
  try {
    value = YAML::Load(assignment.substr(eq + 1));
  } catch (const YAML::Exception& e) {
    // "--set: orb.num_features: malformed value '[': ...", not yaml-cpp's bare message.
    throw InputError(source_name, 0,
                     what + ": malformed value '" + assignment.substr(eq + 1) + "': " + e.msg);
  }
  Assign(f->ptr, value, source_name, 0, what);
  f->origin = Origin{source_name, 0, what};
}

std::optional<ConfigSchema::Origin> ConfigSchema::Blame(
    const std::function<std::string()>& problem) {
  const std::string answer = problem();
  if (answer.empty()) return std::nullopt;
  // The fields the answer names (the key as a whole word) first, then the others.
  auto named = [&answer](const std::string& key) {
    const auto word = [](char c) {
      return std::isalnum(static_cast<unsigned char>(c)) || c == '_';
    };
    for (size_t at = answer.find(key); at != std::string::npos; at = answer.find(key, at + 1)) {
      const size_t end = at + key.size();
      if ((at == 0 || !word(answer[at - 1])) && (end == answer.size() || !word(answer[end])))
        return true;
    }
    return false;
  };
  std::vector<Field*> order;
  for (Field& f : fields_)
    if (f.origin && named(f.key)) order.push_back(&f);
  for (Field& f : fields_)
    if (f.origin && !named(f.key)) order.push_back(&f);
  for (Field* f : order) {
    const Value now = Get(f->ptr);
    Put(f->ptr, f->initial);
    const bool changed = problem() != answer;
    Put(f->ptr, now);
    if (changed) return f->origin;
  }
  return std::nullopt;
}

std::string ConfigSchema::Dump() const {
  YAML::Emitter out;
  out << YAML::BeginMap;
  std::vector<std::string> order;
  for (const Field& f : fields_)
    if (std::find(order.begin(), order.end(), f.section) == order.end()) order.push_back(f.section);
  for (const std::string& section : order) {
    out << YAML::Key << section << YAML::Value << YAML::BeginMap;
    for (const Field& f : fields_) {
      if (f.section != section) continue;
      out << YAML::Key << f.key << YAML::Value;
      std::visit(
          [&](auto* field) {
            // A number as the shortest text that reads back as the same double (0.1, not
            // 0.10000000000000001; 0.5371506532679237 whole, not rounded to 12 digits), so that
            // a rerun with --config OUT/config.yaml runs with exactly the same values.
            if constexpr (std::is_same_v<decltype(*field), double&>) {
              if (std::isfinite(*field)) {
                out << fmt::format("{}", *field);
                return;
              }
            }
            out << *field;
          },
          f.ptr);
      if (!f.doc.empty()) out << YAML::Comment(f.doc);
    }
    out << YAML::EndMap;
  }
  out << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

}  // namespace pcr::driver

#pragma once
// Binds YAML keys (section.key) to fields of plain option structs, so configuration is parsed once
// at the edge: files override the defaults already in the structs; unknown sections/keys, wrong
// types and malformed YAML are InputErrors naming the file and line. Dump() writes the effective
// configuration back as YAML (written next to every run's outputs).
#include <functional>
#include <optional>
#include <string>
#include <variant>
#include <vector>

namespace YAML {
class Node;
}

namespace pcr::driver {

class ConfigSchema {
 public:
  using FieldPtr = std::variant<int*, double*, bool*, std::string*>;

  // Registers section.key. The pointer must outlive the schema.
  void Add(const std::string& section, const std::string& key, FieldPtr field,
           const std::string& doc = "");

  // Applies a YAML file / text on top of the current values.
  void LoadFile(const std::string& path);
  void LoadString(const std::string& text, const std::string& source_name);
  // Applies one "section.key=value" override (as from the command line).
  void Set(const std::string& assignment, const std::string& source_name);

  std::string Dump() const;
  bool Has(const std::string& section, const std::string& key) const;

  // Where a field's value was last set by LoadString/LoadFile/Set: the source name, the key's
  // line (0 for an override) and "section.key".
  struct Origin {
    std::string source;
    int line = 0;
    std::string name;
  };
  // The field to blame for a problem that a check of the whole configuration finds: `problem`
  // returns the check's current answer ("" when none). Each field that a file or an override set
  // is put back to its value when it was registered (the default), one at a time, those whose key
  // the answer names first; the first whose restoration changes the answer is blamed. Every value
  // is as it was on return. nullopt when no single set field changes it (a missing key, say).
  std::optional<Origin> Blame(const std::function<std::string()>& problem);

 private:
  using Value = std::variant<int, double, bool, std::string>;
  struct Field {
    std::string section, key, doc;
    FieldPtr ptr;
    Value initial;  // the value when registered
    std::optional<Origin> origin;
  };
  void Apply(const YAML::Node& root, const std::string& source_name);
  const Field* Find(const std::string& section, const std::string& key) const;
  Field* Find(const std::string& section, const std::string& key);
  std::vector<Field> fields_;
};

}  // namespace pcr::driver

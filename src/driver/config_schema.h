#pragma once
// Binds YAML keys (section.key) to fields of plain option structs, so configuration is parsed once
// at the edge: files override the defaults already in the structs; unknown sections/keys, wrong
// types and malformed YAML are InputErrors naming the file and line. Dump() writes the effective
// configuration back as YAML (written next to every run's outputs).
#include <functional>
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

 private:
  struct Field {
    std::string section, key, doc;
    FieldPtr ptr;
  };
  void Apply(const YAML::Node& root, const std::string& source_name);
  const Field* Find(const std::string& section, const std::string& key) const;
  std::vector<Field> fields_;
};

}  // namespace pcr::driver

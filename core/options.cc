#include "core/options.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>

#include "core/error.h"
#include "core/file_util.h"
#include "core/text.h"

namespace hmc {
namespace {

template <typename T>
T ParseScalar(const YAML::Node& node, const std::string& key,
              const std::filesystem::path& file, int line) {
  try {
    return node.as<T>();
  } catch (const YAML::Exception&) {
    ThrowInputError(file, line, "option '{}': cannot read '{}' as {}", key,
                    node.Scalar(), std::is_same_v<T, double> ? "a number"
                                   : std::is_same_v<T, int>  ? "an integer"
                                   : std::is_same_v<T, bool> ? "true/false"
                                                             : "text");
  }
}

template <typename T>
T ParseValue(const YAML::Node& node, const std::string& name,
             const std::filesystem::path& file, int line) {
  if (!node.IsScalar()) {
    ThrowInputError(file, line, "option '{}' must be a single value", name);
  }
  T value = ParseScalar<T>(node, name, file, line);
  if constexpr (std::is_same_v<T, double>) {
    if (!std::isfinite(value)) {
      ThrowInputError(file, line, "option '{}' is not finite", name);
    }
  }
  return value;
}

template <typename>
struct IsVector : std::false_type {};
template <typename T>
struct IsVector<std::vector<T>> : std::true_type {};

// A list: a YAML sequence of scalars, or one scalar of comma-separated
// items (items trimmed of blanks; empty items skipped).
template <typename T>
std::vector<T> ParseList(const YAML::Node& node, const std::string& name,
                         const std::filesystem::path& file, int line) {
  std::vector<T> out;
  if (node.IsSequence()) {
    for (const auto& item : node) {
      out.push_back(ParseValue<T>(item, name, file, line));
    }
    return out;
  }
  if (!node.IsScalar()) {
    ThrowInputError(file, line, "option '{}' must be a list", name);
  }
  std::stringstream ss(node.Scalar());
  std::string item;
  while (std::getline(ss, item, ',')) {
    const size_t a = item.find_first_not_of(" \t");
    const size_t b = item.find_last_not_of(" \t");
    if (a == std::string::npos) continue;
    out.push_back(
        ParseValue<T>(YAML::Node(item.substr(a, b - a + 1)), name, file, line));
  }
  return out;
}

void AssignFromNode(const OptionFields::Field& field, const YAML::Node& node,
                    const std::filesystem::path& file, int line) {
  field.origin = line > 0 ? fmt::format("{}:{}", file.string(), line) : file.string();
  std::visit(
      [&](auto* pointer) {
        using T = std::remove_pointer_t<decltype(pointer)>;
        if constexpr (IsVector<T>::value) {
          *pointer = ParseList<typename T::value_type>(node, field.name, file,
                                                      line);
        } else {
          *pointer = ParseValue<T>(node, field.name, file, line);
        }
      },
      field.pointer);
}

void Walk(const YAML::Node& node, const std::string& prefix,
          const OptionFields& fields, const std::filesystem::path& file) {
  if (!node.IsMap()) {
    ThrowInputError(file, node.Mark().line + 1,
                    "expected a mapping of option names to values{}",
                    prefix.empty() ? "" : " under '" + prefix + "'");
  }
  for (const auto& entry : node) {
    const std::string key = entry.first.as<std::string>();
    const std::string name = prefix.empty() ? key : prefix + "." + key;
    const int line = entry.first.Mark().line + 1;
    if (const auto* field = fields.Find(name)) {
      AssignFromNode(*field, entry.second, file, line);
      continue;
    }
    bool is_group = false;
    for (const auto& f : fields.fields()) {
      if (f.name.rfind(name + ".", 0) == 0) is_group = true;
    }
    if (!is_group) {
      std::vector<std::string> names;
      for (const auto& f : fields.fields()) names.push_back(f.name);
      const std::string near = NearestWord(name, names, 2);
      ThrowInputError(file, line, "unknown option '{}'{}", name,
                      near.empty() ? "" : "; did you mean '" + near + "'?");
    }
    Walk(entry.second, name, fields, file);
  }
}

}  // namespace

OptionFields::Range OptionFields::AddField(const std::string& name, Pointer pointer,
                                           std::string help) {
  const std::string full = group_.empty() ? name : group_ + "." + name;
  HMC_CHECK_MSG(Find(full) == nullptr, "duplicate option " + full);
  Field field;
  field.name = full;
  field.help = std::move(help);
  field.pointer = pointer;
  fields_.push_back(std::move(field));
  return Range(this, fields_.size() - 1);
}

OptionFields::Range OptionFields::Add(const std::string& name, double* field, std::string help) {
  return AddField(name, field, std::move(help));
}
OptionFields::Range OptionFields::Add(const std::string& name, int* field, std::string help) {
  return AddField(name, field, std::move(help));
}
OptionFields::Range OptionFields::Add(const std::string& name, bool* field, std::string help) {
  return AddField(name, field, std::move(help));
}
OptionFields::Range OptionFields::Add(const std::string& name, std::string* field,
                                      std::string help) {
  return AddField(name, field, std::move(help));
}
OptionFields::Range OptionFields::Add(const std::string& name, std::vector<double>* field,
                                      std::string help) {
  return AddField(name, field, std::move(help));
}
OptionFields::Range OptionFields::Add(const std::string& name, std::vector<std::string>* field,
                                      std::string help) {
  return AddField(name, field, std::move(help));
}

OptionFields::Range& OptionFields::Range::AtLeast(double lo) {
  field().lo = lo;
  field().lo_open = false;
  return *this;
}
OptionFields::Range& OptionFields::Range::Above(double lo) {
  field().lo = lo;
  field().lo_open = true;
  return *this;
}
OptionFields::Range& OptionFields::Range::AtMost(double hi) {
  field().hi = hi;
  field().hi_open = false;
  return *this;
}
OptionFields::Range& OptionFields::Range::Below(double hi) {
  field().hi = hi;
  field().hi_open = true;
  return *this;
}
OptionFields::Range& OptionFields::Range::OneOf(std::vector<std::string> choices) {
  field().choices = std::move(choices);
  return *this;
}

std::string OptionFields::RangeText(const Field& f) {
  if (!f.choices.empty()) return fmt::format("one of {}", fmt::join(f.choices, ", "));
  const bool has_lo = f.lo > -HUGE_VAL, has_hi = f.hi < HUGE_VAL;
  if (has_lo && has_hi) {
    return fmt::format("in {}{}, {}{}", f.lo_open ? "(" : "[", f.lo, f.hi, f.hi_open ? ")" : "]");
  }
  if (has_lo) return fmt::format("{} {}", f.lo_open ? ">" : ">=", f.lo);
  if (has_hi) return fmt::format("{} {}", f.hi_open ? "<" : "<=", f.hi);
  return "";
}

std::string OptionFields::RangeError(const std::string& prefix) const {
  for (const Field& f : fields_) {
    // Every number must be finite, whatever its range (a config or a flag
    // cannot give another; code can).
    auto in_range = [&](double v) {
      return std::isfinite(v) && (f.lo_open ? v > f.lo : v >= f.lo) &&
             (f.hi_open ? v < f.hi : v <= f.hi);
    };
    auto allowed = [&](const std::string& v) {
      return f.choices.empty() || std::find(f.choices.begin(), f.choices.end(), v) != f.choices.end();
    };
    // The value that is not allowed, a list's first such item, as text; and
    // whether it is a number that is not finite. Nothing: all allowed.
    struct Bad {
      std::string text;
      bool non_finite = false;
    };
    const std::optional<Bad> bad = std::visit(
        [&](auto* pointer) -> std::optional<Bad> {
          using T = std::remove_pointer_t<decltype(pointer)>;
          if constexpr (std::is_same_v<T, double> || std::is_same_v<T, int>) {
            const double v = static_cast<double>(*pointer);
            if (in_range(v)) return std::nullopt;
            return Bad{ValueString(f), !std::isfinite(v)};
          } else if constexpr (std::is_same_v<T, std::string>) {
            if (allowed(*pointer)) return std::nullopt;
            return Bad{*pointer};
          } else if constexpr (std::is_same_v<T, std::vector<double>>) {
            for (const double v : *pointer) {
              if (!in_range(v)) return Bad{fmt::format("{}", v), !std::isfinite(v)};
            }
            return std::nullopt;
          } else if constexpr (std::is_same_v<T, std::vector<std::string>>) {
            for (const std::string& v : *pointer) {
              if (!allowed(v)) return Bad{"'" + v + "'"};
            }
            return std::nullopt;
          } else {
            return std::nullopt;
          }
        },
        f.pointer);
    if (bad) {
      const bool list = std::holds_alternative<std::vector<double>*>(f.pointer) ||
                        std::holds_alternative<std::vector<std::string>*>(f.pointer);
      return fmt::format("{}option '{}' = {}{} must be {}",
                         f.origin.empty() ? "" : f.origin + ": ", prefix + f.name,
                         ValueString(f), list ? ": item " + bad->text : "",
                         bad->non_finite ? "finite" : RangeText(f));
    }
  }
  return "";
}

const OptionFields::Field* OptionFields::Find(const std::string& name) const {
  for (const auto& field : fields_) {
    if (field.name == name) return &field;
  }
  return nullptr;
}

namespace {

void RefuseDuplicateKeys(const YAML::Node& node, const std::filesystem::path& file) {
  if (node.IsMap()) {
    std::map<std::string, int> seen;  // key -> line
    for (const auto& item : node) {
      const std::string key = item.first.IsScalar() ? item.first.Scalar() : "";
      const int line = item.first.Mark().line + 1;
      if (item.first.IsScalar()) {
        const auto [it, inserted] = seen.emplace(key, line);
        if (!inserted) {
          ThrowInputError(file, line, "key '{}' given twice in one mapping (first on line {})",
                          key, it->second);
        }
      }
      RefuseDuplicateKeys(item.second, file);
    }
  } else if (node.IsSequence()) {
    for (const auto& item : node) RefuseDuplicateKeys(item, file);
  }
}

}  // namespace

YAML::Node ParseYaml(const std::string& text, const std::filesystem::path& file) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    ThrowInputError(file, e.mark.line >= 0 ? e.mark.line + 1 : 0, "not valid YAML: {}", e.msg);
  }
  RefuseDuplicateKeys(root, file);
  return root;
}

YAML::Node LoadYamlFile(const std::filesystem::path& file) {
  return ParseYaml(ReadFile(file), file);
}

void OptionFields::LoadYaml(const YAML::Node& root,
                            const std::filesystem::path& file) {
  if (!root || root.IsNull()) return;  // An empty config changes nothing.
  Walk(root, "", *this, file);
}

void OptionFields::LoadYamlFile(const std::filesystem::path& file) {
  if (!std::filesystem::exists(file)) {
    ThrowInputError(file, 0, "config file does not exist");
  }
  LoadYaml(hmc::LoadYamlFile(file), file);
}

void OptionFields::Set(const std::string& name, const std::string& value,
                       const std::string& origin) {
  const Field* field = Find(name);
  if (field == nullptr) throw InputError(origin + ": unknown option");
  YAML::Node node;
  try {
    node = YAML::Load(value);
  } catch (const YAML::Exception&) {
    node = YAML::Node(value);
  }
  if (std::holds_alternative<std::string*>(field->pointer) ||
      std::holds_alternative<std::vector<std::string>*>(field->pointer)) {
    node = YAML::Node(value);  // Strings are taken verbatim.
  }
  AssignFromNode(*field, node, origin, 0);
}

std::string OptionFields::ValueString(const Field& field) const {
  return std::visit(
      [](auto* pointer) -> std::string {
        using T = std::remove_pointer_t<decltype(pointer)>;
        if constexpr (std::is_same_v<T, bool>) {
          return *pointer ? "true" : "false";
        } else if constexpr (std::is_same_v<T, std::string>) {
          return *pointer;
        } else if constexpr (std::is_same_v<T, double>) {
          return fmt::format("{}", *pointer);  // Shortest round-trip form.
        } else if constexpr (IsVector<T>::value) {
          return fmt::format("{}", fmt::join(*pointer, ","));
        } else {
          return std::to_string(*pointer);
        }
      },
      field.pointer);
}

YAML::Node OptionFields::ToYaml() const {
  YAML::Node root(YAML::NodeType::Map);
  for (const auto& field : fields_) {
    YAML::Node node = root;
    std::string rest = field.name;
    for (size_t dot; (dot = rest.find('.')) != std::string::npos;) {
      // yaml-cpp nodes are handles: reassigning walks down the tree.
      YAML::Node child = node[rest.substr(0, dot)];
      node.reset(child);
      rest = rest.substr(dot + 1);
    }
    std::visit(
        [&](auto* pointer) {
          using T = std::remove_pointer_t<decltype(pointer)>;
          node[rest] = *pointer;
          if constexpr (IsVector<T>::value) {
            node[rest].SetStyle(YAML::EmitterStyle::Flow);
          }
        },
        field.pointer);
  }
  return root;
}

void WriteOptionsUsed(const OptionFields& fields,
                      const std::filesystem::path& file, const std::string& command) {
  YAML::Emitter out;
  out << fields.ToYaml();
  const std::string mark = command.empty() ? "" : OptionsUsedMark(command) + "\n";
  WriteFileAtomic(file, mark + out.c_str() + "\n");
}

std::string OptionsUsedMark(const std::string& command) {
  return "# options used by hmc " + command + " (docs/formats.md)";
}

}  // namespace hmc

#include "apps/command.h"

#include "core/error.h"

namespace hmc {

OptionBinding::OptionBinding(CLI::App* app, OptionFields fields)
    : fields_(std::move(fields)) {
  app->add_option("--config", config_file_,
                  "YAML file of option values (defaults: configs/); flags on "
                  "the command line override it")
      ->check(CLI::ExistingFile);
  for (const auto& field : fields_.fields()) {
    values_.push_back(std::make_unique<std::string>());
    CLI::Option* flag =
        app->add_option("--" + field.name, *values_.back(), field.help)
            ->default_str(fields_.ValueString(field))
            ->type_name(std::visit(
                [](auto* pointer) -> std::string {
                  using T = std::remove_pointer_t<decltype(pointer)>;
                  if constexpr (std::is_same_v<T, double>) return "NUMBER";
                  if constexpr (std::is_same_v<T, int>) return "INT";
                  if constexpr (std::is_same_v<T, bool>) return "BOOL";
                  if constexpr (std::is_same_v<T, std::vector<double>>) {
                    return "NUMBER,...";
                  }
                  if constexpr (std::is_same_v<T, std::vector<std::string>>) {
                    return "TEXT,...";
                  }
                  return "TEXT";
                },
                field.pointer))
            ->group("Options (also settable in --config)");
    flags_.emplace_back(&field, flag);
  }
}

void OptionBinding::Apply() {
  if (!config_file_.empty()) fields_.LoadYamlFile(config_file_);
  for (size_t i = 0; i < flags_.size(); ++i) {
    if (flags_[i].second->count() > 0) {
      fields_.Set(flags_[i].first->name, *values_[i],
                  "--" + flags_[i].first->name);
    }
  }
}

}  // namespace hmc

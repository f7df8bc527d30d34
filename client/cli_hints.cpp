#include "client/cli_hints.h"

#include <cstdio>
#include <string_view>
#include <vector>

#include "core/base/error.h"

namespace client {

int exitWithHints(const CLI::App& app, const CLI::ParseError& error, int argc, char** argv) {
  // Help and version requests are "errors" to CLI11 too: answered as usual.
  if (error.get_exit_code() == static_cast<int>(CLI::ExitCodes::Success)) return app.exit(error);
  // Walk the words: each one naming a subcommand of the current command
  // enters it; the first that names none is a mistyped command, and a flag
  // the command in hand does not know is a mistyped flag.
  const CLI::App* command = &app;
  std::string hint;
  for (int i = 1; i < argc && hint.empty(); ++i) {
    const std::string_view word = argv[i];
    if (word.empty()) continue;
    if (word.front() != '-') {
      std::vector<std::string> names;
      for (const CLI::App* sub : command->get_subcommands([](const CLI::App*) { return true; })) names.push_back(sub->get_name());
      if (names.empty()) continue;  // a value of the command in hand
      if (const auto found = std::find(names.begin(), names.end(), word); found != names.end()) {
        command = command->get_subcommand(std::string(word));
        continue;
      }
      const std::string near = core::closestName(std::string(word), names);
      if (!near.empty()) hint = "'" + std::string(word) + "' is not a command; did you mean '" + near + "'?";
      continue;
    }
    const std::string flag(word.substr(0, word.find('=')));
    if (flag == "-" || flag == "--") continue;
    std::vector<std::string> names;
    bool known = false;
    for (const CLI::App* owner = command; owner != nullptr && !known; owner = owner->get_parent()) {
      for (const CLI::Option* option : owner->get_options()) {
        for (const std::string& name : option->get_lnames()) {
          names.push_back("--" + name);
          known |= flag == "--" + name;
        }
        for (const std::string& name : option->get_snames()) {
          names.push_back("-" + name);
          known |= flag == "-" + name;
        }
      }
    }
    if (known) continue;
    const std::string near = core::closestName(flag, names);
    if (!near.empty()) hint = "'" + flag + "' is not a flag of " + command->get_name() + "; did you mean '" + near + "'?";
  }
  const int code = app.exit(error);
  if (!hint.empty()) std::fprintf(stderr, "rigport: %s\n", hint.c_str());
  return code;
}

}  // namespace client

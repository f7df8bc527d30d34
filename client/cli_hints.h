// What the CLI says when a command line is wrong: the command or flag a typo
// most likely meant, and output paths it cannot write refused up front.
#pragma once

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <string>

#include <CLI/CLI.hpp>

namespace client {

// An output path rigport can write: binary glTF. One named otherwise
// ("x.fbx") is refused rather than written as GLB under another name; no
// extension at all is taken as meant.
inline const CLI::Validator kGlbPath(
    [](std::string& path) -> std::string {
      std::string extension = std::filesystem::path(path).extension().string();
      std::transform(extension.begin(), extension.end(), extension.begin(),
                     [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
      if (extension.empty() || extension == ".glb") return {};
      return "'" + path + "': rigport writes binary glTF; name the output .glb";
    },
    "GLB");

// The exit for a command line CLI11 refused: its message, and for an unknown
// command or flag the nearest one ("did you mean 'transfer'?").
int exitWithHints(const CLI::App& app, const CLI::ParseError& error, int argc, char** argv);

}  // namespace client

// The CLI of the service client: `rigport rigs ...`, `rigport jobs ...`,
// `rigport bench` and `rigport transfer|fit ... --server URL`. main.cpp only
// constructs RemoteCommands after its own subcommands and asks run() first.
// Every command prints JSON on stdout (bench: its last line) and problems on
// stderr; exit code 0 ok, 1 failed (problem or unsuccessful job).
#pragma once

#include <memory>
#include <optional>

namespace CLI {
class App;
}

namespace client {

struct TransferArgs;
struct FitArgs;

class RemoteCommands {
 public:
  // Adds `rigs`, `jobs` and `bench` to `app`, and --server / --api-key
  // (env RIGPORT_SERVER / RIGPORT_API_KEY) to the existing `transfer` and `fit`.
  RemoteCommands(CLI::App& app, CLI::App& transfer, CLI::App& fit);
  ~RemoteCommands();
  RemoteCommands(const RemoteCommands&) = delete;
  RemoteCommands& operator=(const RemoteCommands&) = delete;

  // After parsing: the exit code when a remote command ran (including
  // `transfer` or `fit` with --server, which then use their parsed flags);
  // nullopt when the chosen subcommand is not remote.
  std::optional<int> run(const TransferArgs& transfer, const FitArgs& fit) const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace client

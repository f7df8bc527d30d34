// The rigport-server binary as a child process, for tests that kill it
// (crash_test, replicas_test): started with the given arguments plus
// --listen 127.0.0.1:0; its first stdout line gives the port.
#pragma once

#include <csignal>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include <httplib.h>

namespace rigport_test {

class ServerProcess {
 public:
  explicit ServerProcess(const std::vector<std::string>& arguments) {
    int out[2];
    if (pipe(out) != 0) return;
    std::vector<std::string> args = {RIGPORT_SERVER_PATH, "--listen", "127.0.0.1:0"};
    args.insert(args.end(), arguments.begin(), arguments.end());
    pid_ = fork();
    if (pid_ == 0) {
      dup2(out[1], STDOUT_FILENO);
      close(out[0]);
      close(out[1]);
      std::vector<char*> argv;
      for (auto& a : args) argv.push_back(a.data());
      argv.push_back(nullptr);
      execv(RIGPORT_SERVER_PATH, argv.data());
      _exit(127);
    }
    close(out[1]);
    FILE* stream = fdopen(out[0], "r");
    char line[256] = {0};
    if (stream && std::fgets(line, sizeof(line), stream)) {
      const std::string text(line);
      port_ = std::atoi(text.substr(text.rfind(':') + 1).c_str());
    }
    if (stream) std::fclose(stream);
  }
  ~ServerProcess() {
    if (pid_ > 0) kill(SIGKILL);
  }
  ServerProcess(const ServerProcess&) = delete;
  ServerProcess& operator=(const ServerProcess&) = delete;

  // Sends `signal` and reaps the process.
  void kill(int signal) {
    if (pid_ <= 0) return;
    ::kill(pid_, signal);
    int status = 0;
    waitpid(pid_, &status, 0);
    pid_ = -1;
  }
  // Sends `signal` and leaves the process be (SIGSTOP, SIGCONT).
  void signal(int signal) const {
    if (pid_ > 0) ::kill(pid_, signal);
  }
  int port() const { return port_; }
  std::unique_ptr<httplib::Client> client() const {
    auto c = std::make_unique<httplib::Client>("127.0.0.1", port_);
    c->set_read_timeout(60, 0);
    return c;
  }

 private:
  pid_t pid_ = -1;
  int port_ = 0;
};

}  // namespace rigport_test

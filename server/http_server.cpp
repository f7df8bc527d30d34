#include "server/http_server.h"

#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <optional>
#include <tuple>

namespace server {
namespace {

using Clock = std::chrono::steady_clock;

// The accept loop hands each socket straight to the gate: no thread is
// taken per connection here (the pool serves requests the gate releases).
class InlineTaskQueue : public httplib::TaskQueue {
 public:
  void enqueue(std::function<void()> fn) override { fn(); }
  void shutdown() override {}
};

// One request's bytes on a socket, read and written under one deadline. Reads
// end (EOF for httplib) at the request's length when it is known, so bytes of
// a next request stay in the socket for the gate, and a POST without a
// length has an empty body instead of one read until the connection closes.
class DeadlineStream final : public httplib::Stream {
 public:
  DeadlineStream(const ReadyConnection& c, Clock::time_point deadline, double read_timeout_s, double write_timeout_s)
      : fd_(c.fd), client_(c.client), client_port_(c.client_port), limit_(c.request_bytes), deadline_(deadline),
        read_timeout_ms_(static_cast<int>(read_timeout_s * 1000)), write_timeout_ms_(static_cast<int>(write_timeout_s * 1000)) {}

  bool is_readable() const override { return pos_ < len_ || wait(POLLIN, read_timeout_ms_); }
  bool is_writable() const override { return wait(POLLOUT, write_timeout_ms_); }

  ssize_t read(char* ptr, size_t size) override {
    if (pos_ == len_) {
      if (limit_ && consumed_ >= *limit_) return 0;
      std::size_t want = sizeof buffer_;
      if (limit_) want = std::min(want, *limit_ - consumed_);
      ssize_t n = -1;
      for (;;) {
        if (!wait(POLLIN, read_timeout_ms_)) return -1;
        n = ::recv(fd_, buffer_, want, MSG_DONTWAIT);
        if (n >= 0 || (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)) break;
      }
      if (n <= 0) return n;
      consumed_ += static_cast<std::size_t>(n);
      pos_ = 0;
      len_ = static_cast<std::size_t>(n);
    }
    const std::size_t n = std::min(size, len_ - pos_);
    std::memcpy(ptr, buffer_ + pos_, n);
    pos_ += n;
    return static_cast<ssize_t>(n);
  }

  ssize_t write(const char* ptr, size_t size) override {
    for (;;) {
      if (!wait(POLLOUT, write_timeout_ms_)) return -1;
      const ssize_t n = ::send(fd_, ptr, size, MSG_NOSIGNAL | MSG_DONTWAIT);
      if (n >= 0 || (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)) return n;
    }
  }

  void get_remote_ip_and_port(std::string& ip, int& port) const override {
    ip = client_;
    port = client_port_;
  }
  void get_local_ip_and_port(std::string& ip, int& port) const override {
    sockaddr_storage local{};
    socklen_t length = sizeof local;
    ip.clear();
    port = 0;
    if (getsockname(fd_, reinterpret_cast<sockaddr*>(&local), &length) == 0) std::tie(ip, port) = addressText(local);
  }
  socket_t socket() const override { return fd_; }

  // The request was read to its end and nothing past it: the connection can
  // carry the next one.
  bool atRequestEnd() const { return limit_ && consumed_ == *limit_ && pos_ == len_; }

 private:
  // Ready within min(timeout, time left to the deadline)?
  bool wait(short events, int timeout_ms) const {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline_ - Clock::now()).count();
    if (left <= 0) return false;
    pollfd p{fd_, events, 0};
    const int r = ::poll(&p, 1, static_cast<int>(std::min<long long>(left, timeout_ms)));
    return r > 0 && (p.revents & (events | POLLHUP | POLLERR));
  }

  int fd_;
  std::string client_;
  int client_port_;
  std::optional<std::size_t> limit_;
  Clock::time_point deadline_;
  int read_timeout_ms_, write_timeout_ms_;
  char buffer_[4096];
  std::size_t pos_ = 0, len_ = 0, consumed_ = 0;
};

}  // namespace

GatedHttpServer::GatedHttpServer(HttpLimits limits, GateEvent on_event)
    : limits_(limits),
      gate_(limits.gate, [this](ReadyConnection c) { pool_->enqueue([this, c] { serve(c); }); }, std::move(on_event)),
      pool_(std::make_unique<httplib::ThreadPool>(static_cast<std::size_t>(std::max(1, limits.threads)))) {
  new_task_queue = [] { return new InlineTaskQueue(); };
  gate_.start();
}

GatedHttpServer::~GatedHttpServer() { drain(); }

void GatedHttpServer::drain() {
  if (draining_.exchange(true)) return;
  gate_.stop();
  pool_->shutdown();  // requests in service finish; each is time-bounded
}

bool GatedHttpServer::process_and_close_socket(socket_t sock) {
  gate_.admit(sock, 0);
  return true;
}

void GatedHttpServer::serve(const ReadyConnection& connection) {
  const double limit_s = connection.upload ? limits_.upload_time_s : limits_.request_time_s;
  const auto deadline = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(limit_s));
  DeadlineStream stream(connection, deadline, limits_.read_timeout_s, limits_.write_timeout_s);
  const bool last = draining_ || connection.served + 1 >= limits_.keep_alive_max_count;
  bool closed = false;
  const bool ok = process_request(stream, last, closed, nullptr);
  if (ok && !closed && !last && !draining_ && stream.atRequestEnd()) {
    gate_.admit(connection.fd, connection.served + 1);
    return;
  }
  ::shutdown(connection.fd, SHUT_RDWR);
  ::close(connection.fd);
}

}  // namespace server

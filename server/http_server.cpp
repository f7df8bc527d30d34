#include "server/http_server.h"

#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <csignal>
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

// One request's bytes on a connection, read and written under one deadline:
// first what the gate already read, then the connection's own. Reads end
// (EOF for httplib) at the request's length when it is known, so bytes of a
// next request stay for the gate, and a POST without a length has an empty
// body instead of one read until the connection closes.
class DeadlineStream final : public httplib::Stream {
 public:
  DeadlineStream(ReadyConnection& c, Clock::time_point deadline, double read_timeout_s, double write_timeout_s)
      : connection_(*c.connection), client_(c.client), client_port_(c.client_port), limit_(c.request_bytes),
        deadline_(deadline), read_timeout_ms_(static_cast<int>(read_timeout_s * 1000)),
        write_timeout_ms_(static_cast<int>(write_timeout_s * 1000)), buffer_(std::move(c.received)) {
    len_ = limit_ ? std::min(buffer_.size(), *limit_) : buffer_.size();
    consumed_ = len_;
    if (buffer_.size() > len_) beyond_ = buffer_.substr(len_);
  }

  bool is_readable() const override {
    return pos_ < len_ || connection_.hasPending() || wait(IoResult::Kind::kWantRead, read_timeout_ms_);
  }
  bool is_writable() const override { return wait(IoResult::Kind::kWantWrite, write_timeout_ms_); }

  ssize_t read(char* ptr, size_t size) override {
    if (pos_ == len_) {
      if (limit_ && consumed_ >= *limit_) return 0;
      std::size_t want = kChunk;
      if (limit_) want = std::min(want, *limit_ - consumed_);
      if (buffer_.size() < want) buffer_.resize(want);
      IoResult r;
      for (;;) {
        r = connection_.receive(buffer_.data(), want);
        if (r.kind != IoResult::Kind::kWantRead && r.kind != IoResult::Kind::kWantWrite) break;
        if (!wait(r.kind, read_timeout_ms_)) return -1;
      }
      if (r.kind == IoResult::Kind::kClosed) return 0;
      if (r.kind != IoResult::Kind::kBytes) return -1;
      consumed_ += r.bytes;
      pos_ = 0;
      len_ = r.bytes;
    }
    const std::size_t n = std::min(size, len_ - pos_);
    std::memcpy(ptr, buffer_.data() + pos_, n);
    pos_ += n;
    return static_cast<ssize_t>(n);
  }

  ssize_t write(const char* ptr, size_t size) override {
    for (;;) {
      const IoResult r = connection_.send(ptr, size);
      if (r.kind == IoResult::Kind::kBytes) return static_cast<ssize_t>(r.bytes);
      if (r.kind != IoResult::Kind::kWantRead && r.kind != IoResult::Kind::kWantWrite) return -1;
      if (!wait(r.kind, write_timeout_ms_)) return -1;
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
    if (getsockname(connection_.fd(), reinterpret_cast<sockaddr*>(&local), &length) == 0) {
      std::tie(ip, port) = addressText(local);
    }
  }
  socket_t socket() const override { return connection_.fd(); }

  // The request was read to its end: the connection can carry the next one,
  // whose first bytes (if any came with this one) are these.
  bool atRequestEnd() const { return limit_ && consumed_ == *limit_ && pos_ == len_; }
  std::string takeBeyondRequest() { return std::move(beyond_); }

 private:
  static constexpr std::size_t kChunk = 16384;

  // Ready within min(timeout, time left to the deadline)?
  bool wait(IoResult::Kind direction, int timeout_ms) const {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline_ - Clock::now()).count();
    if (left <= 0) return false;
    const short events = direction == IoResult::Kind::kWantWrite ? POLLOUT : POLLIN;
    pollfd p{connection_.fd(), events, 0};
    const int r = ::poll(&p, 1, static_cast<int>(std::min<long long>(left, timeout_ms)));
    return r > 0 && (p.revents & (events | POLLHUP | POLLERR));
  }

  Connection& connection_;
  std::string client_;
  int client_port_;
  std::optional<std::size_t> limit_;
  Clock::time_point deadline_;
  int read_timeout_ms_, write_timeout_ms_;
  std::string buffer_;  // [pos_, len_) not yet given to httplib
  std::string beyond_;  // read by the gate past this request's end
  std::size_t pos_ = 0, len_ = 0, consumed_ = 0;
};

}  // namespace

GatedHttpServer::GatedHttpServer(HttpLimits limits, std::shared_ptr<const TlsContext> tls, GateEvent on_event)
    : limits_(limits),
      tls_(std::move(tls)),
      gate_(limits.gate, [this](ReadyConnection c) { pool_->enqueue([this, c = std::move(c)]() mutable { serve(std::move(c)); }); }, std::move(on_event)),
      pool_(std::make_unique<httplib::ThreadPool>(static_cast<std::size_t>(std::max(1, limits.threads)))) {
  // OpenSSL writes with write(2), which raises SIGPIPE on a connection the
  // client has closed: that must end the write, not the process.
  if (tls_) std::signal(SIGPIPE, SIG_IGN);
  new_task_queue = [] { return new InlineTaskQueue(); };
  // SO_REUSEADDR only: httplib's default SO_REUSEPORT would let a second
  // server start on the same port and take a share of its connections.
  set_socket_options([this](socket_t sock) {
    const int yes = 1;
    setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
    listen_fd_ = sock;
  });
  gate_.start();
}

int GatedHttpServer::bindListener(const std::string& host, int port, int backlog) {
  const int bound = port == 0 ? bind_to_any_port(host) : (bind_to_port(host, port) ? port : -1);
  // httplib listens with a backlog of 5: a burst of new connections beyond
  // that would wait for SYN retransmits (1 s, 3 s, ...). listen() again on
  // the bound socket only resizes its queue.
  if (bound > 0 && listen_fd_ >= 0) ::listen(listen_fd_, backlog);
  return bound;
}

GatedHttpServer::~GatedHttpServer() { drain(); }

void GatedHttpServer::drain() {
  if (draining_.exchange(true)) return;
  gate_.stop();
  pool_->shutdown();  // requests in service finish; each is time-bounded
}

bool GatedHttpServer::process_and_close_socket(socket_t sock) {
  SSL* session = nullptr;
  if (tls_ && !(session = tls_->newSession(sock))) {
    ::close(sock);
    return false;
  }
  gate_.admit(std::make_shared<Connection>(sock, session), 0);
  return true;
}

void GatedHttpServer::serve(ReadyConnection connection) {
  const double limit_s = connection.upload ? limits_.upload_time_s : limits_.request_time_s;
  const auto deadline = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(limit_s));
  DeadlineStream stream(connection, deadline, limits_.read_timeout_s, limits_.write_timeout_s);
  const bool last = draining_ || connection.served + 1 >= limits_.keep_alive_max_count;
  bool closed = false;
  const bool ok = process_request(stream, last, closed, nullptr);
  if (ok && !closed && !last && !draining_ && stream.atRequestEnd()) {
    gate_.admit(std::move(connection.connection), connection.served + 1, stream.takeBeyondRequest());
    return;
  }
  connection.connection->close();
}

}  // namespace server

#include "server/connection_gate.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <string_view>
#include <tuple>

#include "api/error_codes.h"
#include "core/base/text.h"
#include "api/json.h"

namespace server {
namespace {

using Clock = std::chrono::steady_clock;

Clock::time_point after(double seconds) {
  return Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
}

bool equalsIgnoreCase(std::string_view a, std::string_view b) {
  return a.size() == b.size() &&
         std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) { return std::tolower(x) == std::tolower(y); });
}

// What the door needs to know of a complete request head.
struct Head {
  std::string method, path;
  std::optional<std::size_t> content_length;
  bool chunked = false;
  bool expects_continue = false;
};

// The head's request line and framing headers, or the problem with it.
api::Result<Head> parseHead(std::string_view head) {
  const auto bad = [](const std::string& detail, const std::string& path) {
    return api::makeProblem(api::WireError::kMalformedRequest, detail, path.empty() ? "/" : path);
  };
  Head out;
  // RFC 9110 5.5 / RFC 9112 2.2: NUL and a CR not before LF are refused, not
  // passed on to a parser that might read them otherwise.
  if (head.find('\0') != std::string_view::npos) return bad("the request head holds a NUL byte", "");
  for (std::size_t at = head.find('\r'); at != std::string_view::npos; at = head.find('\r', at + 1)) {
    if (at + 1 >= head.size() || head[at + 1] != '\n') return bad("the request head holds a CR not followed by LF", "");
  }
  std::size_t line_end = head.find("\r\n");
  const std::string_view request_line = head.substr(0, line_end);
  const std::size_t sp1 = request_line.find(' ');
  const std::size_t sp2 = sp1 == std::string_view::npos ? sp1 : request_line.find(' ', sp1 + 1);
  if (sp2 == std::string_view::npos || request_line.substr(sp2 + 1).substr(0, 7) != "HTTP/1.") {
    return bad("the request line is not 'METHOD target HTTP/1.x'", "");
  }
  out.method = request_line.substr(0, sp1);
  const std::string_view target = request_line.substr(sp1 + 1, sp2 - sp1 - 1);
  out.path = target.substr(0, target.find('?'));
  while (line_end + 2 < head.size()) {
    const std::size_t start = line_end + 2;
    line_end = head.find("\r\n", start);
    const std::string_view line = head.substr(start, line_end - start);
    if (line.empty()) break;
    const std::size_t colon = line.find(':');
    if (colon == std::string_view::npos) continue;  // httplib judges the rest of the head
    const std::string_view name = line.substr(0, colon);
    const std::string_view value = core::trim(line.substr(colon + 1));
    if (equalsIgnoreCase(name, "Content-Length")) {
      std::size_t length = 0;
      const auto [end, ec] = std::from_chars(value.data(), value.data() + value.size(), length);
      if (ec != std::errc() || end != value.data() + value.size()) {
        return bad("Content-Length '" + std::string(value) + "' is not a byte count", out.path);
      }
      if (out.content_length && *out.content_length != length) return bad("two different Content-Length headers", out.path);
      out.content_length = length;
    } else if (equalsIgnoreCase(name, "Transfer-Encoding")) {
      out.chunked = true;
    } else if (equalsIgnoreCase(name, "Expect")) {
      out.expects_continue = true;
    }
  }
  // Both lengths at once is how requests are smuggled past proxies (RFC 9112 6.3).
  if (out.chunked && out.content_length) return bad("both Transfer-Encoding and Content-Length", out.path);
  return out;
}

bool isUploadRoute(const Head& head) {
  return head.method == "POST" && (head.path == "/v1/rigs" || head.path == "/v1/jobs");
}

const char* reasonPhrase(int status) {
  switch (status) {
    case 400: return "Bad Request";
    case 408: return "Request Timeout";
    case 411: return "Length Required";
    case 413: return "Content Too Large";
    case 431: return "Request Header Fields Too Large";
    default: return "Error";
  }
}

}  // namespace

std::pair<std::string, int> addressText(const sockaddr_storage& address) {
  char text[INET6_ADDRSTRLEN] = {};
  if (address.ss_family == AF_INET) {
    const auto* in = reinterpret_cast<const sockaddr_in*>(&address);
    inet_ntop(AF_INET, &in->sin_addr, text, sizeof text);
    return {text, ntohs(in->sin_port)};
  }
  if (address.ss_family == AF_INET6) {
    const auto* in6 = reinterpret_cast<const sockaddr_in6*>(&address);
    inet_ntop(AF_INET6, &in6->sin6_addr, text, sizeof text);
    return {text, ntohs(in6->sin6_port)};
  }
  return {"", 0};
}

ConnectionGate::ConnectionGate(GateLimits limits, Dispatch dispatch, Event on_event)
    : limits_(limits), dispatch_(std::move(dispatch)), on_event_(std::move(on_event)) {}

ConnectionGate::~ConnectionGate() { stop(); }

void ConnectionGate::start() {
  if (thread_.joinable()) return;
  epoll_fd_ = epoll_create1(EPOLL_CLOEXEC);
  wake_fd_ = eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
  epoll_event ev{};
  ev.events = EPOLLIN;
  ev.data.fd = wake_fd_;
  epoll_ctl(epoll_fd_, EPOLL_CTL_ADD, wake_fd_, &ev);
  thread_ = std::thread([this] { run(); });
}

void ConnectionGate::stop() {
  {
    std::lock_guard lock(mutex_);
    if (stopping_) return;
    stopping_ = true;
  }
  if (thread_.joinable()) {
    const std::uint64_t one = 1;
    [[maybe_unused]] const auto n = ::write(wake_fd_, &one, sizeof one);
    thread_.join();
  }
  std::lock_guard lock(mutex_);
  for (auto& in : incoming_) in.connection->close();
  incoming_.clear();
  if (epoll_fd_ >= 0) ::close(epoll_fd_);
  if (wake_fd_ >= 0) ::close(wake_fd_);
  epoll_fd_ = wake_fd_ = -1;
}

void ConnectionGate::admit(std::shared_ptr<Connection> connection, int served, std::string received) {
  {
    std::lock_guard lock(mutex_);
    if (!stopping_ && thread_.joinable()) {
      incoming_.push_back({std::move(connection), served, std::move(received)});
      const std::uint64_t one = 1;
      [[maybe_unused]] const auto n = ::write(wake_fd_, &one, sizeof one);
      return;
    }
  }
  connection->close();
}

int ConnectionGate::waiting() const {
  std::lock_guard lock(mutex_);
  return waiting_count_;
}

void ConnectionGate::run() {
  std::vector<epoll_event> events(256);
  for (;;) {
    // Deadlines are checked at least every 100 ms.
    const int n = epoll_wait(epoll_fd_, events.data(), static_cast<int>(events.size()), 100);
    std::vector<Incoming> incoming;
    {
      std::lock_guard lock(mutex_);
      if (stopping_) break;
      incoming.swap(incoming_);
    }
    for (int i = 0; i < n; ++i) {
      const int fd = events[i].data.fd;
      if (fd == wake_fd_) {
        std::uint64_t count = 0;
        [[maybe_unused]] const auto r = ::read(wake_fd_, &count, sizeof count);
      } else if (waiting_.count(fd)) {
        inspect(fd);
      }
    }
    for (auto& in : incoming) take(std::move(in));
    expire();
    std::lock_guard lock(mutex_);
    waiting_count_ = static_cast<int>(waiting_.size());
  }
  for (auto& [fd, w] : waiting_) w.connection->close();
  waiting_.clear();
  per_client_.clear();
}

void ConnectionGate::take(Incoming incoming) {
  const int fd = incoming.connection->fd();
  Waiting w;
  sockaddr_storage peer{};
  socklen_t length = sizeof peer;
  if (getpeername(fd, reinterpret_cast<sockaddr*>(&peer), &length) == 0) {
    std::tie(w.client, w.client_port) = addressText(peer);
  }
  if (incoming.served == 0) {
    // httplib writes a response's head and body separately; with Nagle's
    // algorithm the body then waits for the client's delayed ACK (40 ms per
    // request on a kept-alive connection).
    const int on = 1;
    setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &on, sizeof on);
  }
  w.connection = std::move(incoming.connection);
  w.received = std::move(incoming.received);
  w.served = incoming.served;
  w.order = next_order_++;
  w.deadline = after(incoming.served == 0 ? limits_.head_timeout_s : limits_.keep_alive_idle_s);
  // Edge-triggered: each new segment fires once, and every read goes on
  // until the socket has no more (or the connection is decided).
  w.watched = EPOLLIN | EPOLLRDHUP | EPOLLET;
  epoll_event ev{};
  ev.events = w.watched;
  ev.data.fd = fd;
  if (epoll_ctl(epoll_fd_, EPOLL_CTL_ADD, fd, &ev) != 0) {
    w.connection->close();
    return;
  }
  const std::string client = w.client;
  waiting_.emplace(fd, std::move(w));
  if (++per_client_[client] > limits_.max_waiting_per_client) evictOldest(&client, "connection_evicted_per_client");
  if (static_cast<int>(waiting_.size()) > limits_.max_waiting) evictOldest(nullptr, "connection_evicted");
  if (waiting_.count(fd)) inspect(fd);  // bytes that came before it was watched raise no edge
}

void ConnectionGate::watch(int fd, Waiting& w, IoResult::Kind waiting_for) {
  const std::uint32_t wanted =
      EPOLLIN | EPOLLRDHUP | EPOLLET | (waiting_for == IoResult::Kind::kWantWrite ? EPOLLOUT : 0u);
  if (wanted == w.watched) return;
  w.watched = wanted;
  epoll_event ev{};
  ev.events = wanted;
  ev.data.fd = fd;
  epoll_ctl(epoll_fd_, EPOLL_CTL_MOD, fd, &ev);
}

bool ConnectionGate::readAvailable(Waiting& w) {
  // Enough for the largest head and small body, and one byte to tell a head
  // that is too long.
  const std::size_t cap = limits_.max_head_bytes + limits_.max_small_body_bytes + 1;
  char chunk[16384];
  while (w.received.size() < cap) {
    const IoResult r = w.connection->receive(chunk, std::min(sizeof chunk, cap - w.received.size()));
    switch (r.kind) {
      case IoResult::Kind::kBytes: w.received.append(chunk, r.bytes); break;
      case IoResult::Kind::kClosed: w.peer_closed = true; return true;
      case IoResult::Kind::kWantRead:
      case IoResult::Kind::kWantWrite: watch(w.connection->fd(), w, r.kind); return true;
      case IoResult::Kind::kFailed: return false;
    }
  }
  return true;
}

void ConnectionGate::inspect(int fd) {
  Waiting& w = waiting_.at(fd);
  if (!w.connection->established()) {
    const IoResult r = w.connection->handshake();
    if (r.kind == IoResult::Kind::kWantRead || r.kind == IoResult::Kind::kWantWrite) return watch(fd, w, r.kind);
    if (r.kind == IoResult::Kind::kFailed) return close(fd, "tls_handshake_failed", r.error);
    if (r.kind == IoResult::Kind::kClosed) return close(fd, "");
  }
  if (!readAvailable(w)) return close(fd, "");
  if (w.received.empty()) {
    if (w.peer_closed) close(fd, "");  // the client went away
    return;
  }
  if (!w.started) {  // the head's time runs from its first byte (an idle keep-alive had its own)
    w.started = true;
    w.deadline = after(limits_.head_timeout_s);
  }
  const std::string_view bytes(w.received);
  const std::size_t end = bytes.find("\r\n\r\n");
  if (end == std::string_view::npos || end + 4 > limits_.max_head_bytes) {
    if (bytes.size() >= limits_.max_head_bytes) {
      return answer(fd, api::makeProblem(api::WireError::kHeadersTooLarge,
                                         "the request head is over " + std::to_string(limits_.max_head_bytes) + " bytes",
                                         "/"));
    }
    if (w.peer_closed) close(fd, "");  // it will never be complete
    return;                            // not complete yet: wait for more
  }
  auto parsed = parseHead(bytes.substr(0, end + 4));
  if (!parsed) return answer(fd, parsed.error());
  const Head& head = *parsed;
  ReadyConnection ready;
  ready.client = w.client;
  ready.client_port = w.client_port;
  ready.served = w.served;
  ready.head_bytes = end + 4;
  ready.upload = isUploadRoute(head);
  if (!ready.upload) {
    if (head.chunked) {
      return answer(fd, api::makeProblem(api::WireError::kLengthRequired,
                                         "a body on " + head.method + " " + head.path +
                                             " must be sent with Content-Length (only uploads may be chunked)",
                                         head.path));
    }
    const std::size_t body = head.content_length.value_or(0);
    if (body > limits_.max_small_body_bytes) {
      return answer(fd, api::makeProblem(api::WireError::kPayloadTooLarge,
                                         head.method + " " + head.path + " takes a body of at most " +
                                             std::to_string(limits_.max_small_body_bytes) + " bytes",
                                         head.path));
    }
    // The whole small body must be here too (unless the client waits for
    // 100 Continue before sending it), so no thread waits on it.
    if (!head.expects_continue && bytes.size() < ready.head_bytes + body) {
      if (w.peer_closed) close(fd, "");
      return;
    }
  }
  // No length and not chunked: the body is empty (RFC 9112 6.3), whatever
  // the method; the stream ends there for httplib, which would otherwise
  // read until the connection closes.
  if (!head.chunked) ready.request_bytes = ready.head_bytes + head.content_length.value_or(0);
  epoll_ctl(epoll_fd_, EPOLL_CTL_DEL, fd, nullptr);
  if (--per_client_[w.client] <= 0) per_client_.erase(w.client);
  ready.connection = std::move(w.connection);
  ready.received = std::move(w.received);
  waiting_.erase(fd);
  dispatch_(std::move(ready));
}

void ConnectionGate::close(int fd, const std::string& event, const std::string& detail) {
  auto it = waiting_.find(fd);
  if (it == waiting_.end()) return;
  if (!event.empty() && on_event_) on_event_(event, it->second.client, detail);
  if (--per_client_[it->second.client] <= 0) per_client_.erase(it->second.client);
  epoll_ctl(epoll_fd_, EPOLL_CTL_DEL, fd, nullptr);
  it->second.connection->close();
  waiting_.erase(it);
}

void ConnectionGate::answer(int fd, const api::Problem& problem) {
  Connection& connection = *waiting_.at(fd).connection;
  const std::string body = api::dumpJson(api::toJson(problem));
  const std::string response = "HTTP/1.1 " + std::to_string(problem.status) + " " + reasonPhrase(problem.status) +
                               "\r\nContent-Type: application/problem+json\r\nContent-Length: " +
                               std::to_string(body.size()) + "\r\nConnection: close\r\n\r\n" + body;
  // Best effort: a client that does not read its answer just loses it.
  connection.send(response.data(), response.size());
  // What the client sent and we did not read would make close() reset the
  // connection, and a reset can discard the answer before the client reads
  // it: what is already here is read and dropped.
  char sink[16384];
  for (int i = 0; i < 64 && connection.receive(sink, sizeof sink).kind == IoResult::Kind::kBytes; ++i) {
  }
  if (on_event_) on_event_("request_refused_at_gate", waiting_.at(fd).client, problem.detail);
  close(fd, "");
}

void ConnectionGate::expire() {
  const auto now = Clock::now();
  std::vector<int> late;
  for (const auto& [fd, w] : waiting_) {
    if (w.deadline <= now) late.push_back(fd);
  }
  for (int fd : late) {
    const Waiting& w = waiting_.at(fd);
    if (w.started && w.connection->established()) {
      answer(fd, api::makeProblem(api::WireError::kRequestTimeout,
                                  "the request head did not arrive within " +
                                      std::to_string(static_cast<int>(limits_.head_timeout_s)) + " s",
                                  "/"));
    } else {
      close(fd, "");  // idle: a new connection that sent nothing, or a kept-alive one
    }
  }
}

void ConnectionGate::evictOldest(const std::string* client, const std::string& event) {
  int oldest = -1;
  std::uint64_t order = UINT64_MAX;
  for (const auto& [fd, w] : waiting_) {
    if ((!client || w.client == *client) && w.order < order) {
      order = w.order;
      oldest = fd;
    }
  }
  if (oldest >= 0) close(oldest, event);
}

}  // namespace server

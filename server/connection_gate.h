// The door in front of the HTTP threads. cpp-httplib gives a connection a
// thread for as long as it is open and times out each read on its own, so a
// client sending its request head a byte every few seconds (slowloris), or a
// POST with no length whose body httplib reads until the connection closes,
// holds a thread indefinitely; a few dozen of them leave none for anybody.
//
// Here a connection takes no thread until its whole request head (and, for
// a route that takes no upload, its whole small body) has arrived: one
// thread watches every waiting socket (epoll), drives TLS handshakes and
// reads what comes into the connection's own buffer, which travels with it
// to the HTTP thread (server/http_server.h) and back for a kept-alive
// connection's next request. A head not complete within head_timeout is
// answered 408 and closed (a TLS handshake not done by then, closed); an
// idle keep-alive connection is closed after its idle timeout; a client address holding more than max_waiting_per_client
// waiting connections loses its oldest, so one address cannot fill the door
// while a well-behaved request from anywhere still gets through at once.
// Requests the door can judge alone are answered here without a thread: 431
// (head over max_head_bytes), 413 (a body over max_small_body_bytes on a
// route that takes no upload), 411 (a chunked body on such a route), 400 (a
// head that is not HTTP/1.x, conflicting lengths).
#pragma once

#include <sys/socket.h>

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <unordered_map>
#include <vector>

#include "api/types.h"
#include "server/connection.h"

namespace server {

struct GateLimits {
  double head_timeout_s = 10.0;            // whole request head, from its first byte (or from accept)
  double keep_alive_idle_s = 2.0;          // between requests on one connection
  std::size_t max_head_bytes = 16 << 10;   // request line + headers
  std::size_t max_small_body_bytes = 64 << 10;  // a body on a route that takes no upload
  int max_waiting = 4096;                  // waiting connections in all
  int max_waiting_per_client = 64;         // waiting connections of one client address
};

// A connection whose next request is ready to be served.
struct ReadyConnection {
  std::shared_ptr<Connection> connection;
  // Bytes read from it already: the whole head, then as much of the body
  // (and possibly of a next, pipelined request) as had arrived.
  std::string received;
  std::string client;       // peer address (IP text)
  int client_port = 0;
  int served = 0;           // requests already served on it
  std::size_t head_bytes = 0;
  // Bytes of the request (head + body) when its length is known; nullopt for
  // a chunked upload (the connection then closes after it).
  std::optional<std::size_t> request_bytes;
  bool upload = false;      // POST /v1/rigs or /v1/jobs: body read on the thread, under the upload limits
};

// "127.0.0.1" and the port of an IPv4 or IPv6 socket address ("", 0 otherwise).
std::pair<std::string, int> addressText(const struct sockaddr_storage& address);

class ConnectionGate {
 public:
  using Dispatch = std::function<void(ReadyConnection)>;
  using Event = std::function<void(const std::string& event, const std::string& client, const std::string& detail)>;
  // `dispatch` runs on the gate's thread: it must only hand the connection on.
  ConnectionGate(GateLimits limits, Dispatch dispatch, Event on_event);
  ~ConnectionGate();  // stop()
  ConnectionGate(const ConnectionGate&) = delete;
  ConnectionGate& operator=(const ConnectionGate&) = delete;

  void start();
  // Closes every waiting connection; admit() then closes what it is given.
  void stop();
  // A new connection (served = 0) or a kept-alive one coming back after
  // `served` requests with `received`, bytes read past its last request.
  // Any thread.
  void admit(std::shared_ptr<Connection> connection, int served, std::string received = {});
  int waiting() const;

 private:
  struct Incoming {
    std::shared_ptr<Connection> connection;
    int served = 0;
    std::string received;
  };
  struct Waiting {
    std::shared_ptr<Connection> connection;
    std::string received;                       // read so far: this request's head and small body
    std::string client;
    int client_port = 0;
    int served = 0;
    std::uint64_t order = 0;                    // admission order: the oldest is evicted first
    std::chrono::steady_clock::time_point deadline;
    bool started = false;                       // a byte of the next head (or of the TLS handshake) has arrived
    bool peer_closed = false;                   // the client sent its last byte (maybe a whole request)
    std::uint32_t watched = 0;                  // epoll events asked for
  };
  void run();
  void take(Incoming incoming);                  // on the gate thread
  void inspect(int fd);                          // read: dispatch, answer, keep waiting or close
  bool readAvailable(Waiting& w);                // false: the connection failed (closed)
  void watch(int fd, Waiting& w, IoResult::Kind waiting_for);
  void close(int fd, const std::string& event, const std::string& detail = "");  // event "": silently
  void answer(int fd, const api::Problem& problem);  // then closes
  void expire();
  void evictOldest(const std::string* client, const std::string& event);

  const GateLimits limits_;
  const Dispatch dispatch_;
  const Event on_event_;
  int epoll_fd_ = -1;
  int wake_fd_ = -1;
  std::thread thread_;
  mutable std::mutex mutex_;                    // incoming_, stopping_, waiting_count_
  std::vector<Incoming> incoming_;              // admitted, not yet taken
  bool stopping_ = false;
  int waiting_count_ = 0;
  // Gate thread only.
  std::unordered_map<int, Waiting> waiting_;
  std::map<std::string, int> per_client_;
  std::uint64_t next_order_ = 0;
};

}  // namespace server

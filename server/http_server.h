// cpp-httplib's server behind the ConnectionGate (server/connection_gate.h):
// accepted connections wait at the gate, without a thread, until their
// request is there; then one request is served on a pool thread and a
// kept-alive connection goes back to the gate for its next one. A request's
// time on a thread is bounded as a whole, not per read: reading its body
// and writing its response stop at request_time_s (upload_time_s for the
// uploads), so a client trickling a byte at a time cannot hold a thread.
// With a TlsContext the same is served over TLS: the gate drives the
// handshakes, so a client that stalls one holds no thread either.
#pragma once

#include <atomic>
#include <memory>

#include "api/http.h"
#include "server/connection_gate.h"

namespace server {

struct HttpLimits {
  int threads = 32;
  int keep_alive_max_count = 100;   // requests per connection
  double read_timeout_s = 30.0;     // one read or write waits at most this long
  double write_timeout_s = 30.0;
  double request_time_s = 120.0;    // a request on a thread, body and response included (a long-poll waits <= 60 s)
  double upload_time_s = 600.0;     // the same for POST /v1/rigs and /v1/jobs
  GateLimits gate;
};

class GatedHttpServer : public httplib::Server {
 public:
  using GateEvent = ConnectionGate::Event;
  // `tls`: serve HTTPS with it; null: plain HTTP.
  GatedHttpServer(HttpLimits limits, std::shared_ptr<const TlsContext> tls, GateEvent on_event);
  ~GatedHttpServer() override;
  // Binds host:port (port 0: any free port) with a listen backlog of
  // `backlog` pending connections; the bound port, or -1.
  int bindListener(const std::string& host, int port, int backlog);
  // After httplib's stop(): closes the waiting connections and lets the
  // requests in service finish (each within its time bound).
  void drain();
  int waitingConnections() const { return gate_.waiting(); }

 private:
  // Called by httplib for each accepted socket (on its accept thread, the
  // task queue being inline): hands it to the gate.
  bool process_and_close_socket(socket_t sock) override;
  void serve(ReadyConnection connection);

  const HttpLimits limits_;
  const std::shared_ptr<const TlsContext> tls_;
  ConnectionGate gate_;
  std::unique_ptr<httplib::ThreadPool> pool_;
  std::atomic<bool> draining_{false};
  int listen_fd_ = -1;  // the listening socket, as httplib created it
};

}  // namespace server

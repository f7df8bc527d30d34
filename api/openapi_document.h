// The OpenAPI 3 document of the contract (api/openapi.json, compiled in so
// the server serves exactly the file in the repository at /openapi.json).
#pragma once

#include <string_view>

namespace api {

std::string_view openApiDocument();

}  // namespace api

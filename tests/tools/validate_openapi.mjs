// Validates an OpenAPI document against the OpenAPI 3.x schema
// (@seriousme/openapi-schema-validator, installed by docker/install-deps.sh)
// and prints {"valid": bool, "errors": [...]}. Exit code 0 when valid, 1 when
// not, 2 when the validator is missing.
import path from 'path';
import { pathToFileURL } from 'url';

const modulesDir = process.env.RIGPORT_TOOLS_DIR
  ? path.join(process.env.RIGPORT_TOOLS_DIR, 'node_modules')
  : path.join(path.dirname(new URL(import.meta.url).pathname), '..', '..', '.tools', 'node_modules');
let Validator;
try {
  ({ Validator } = await import(pathToFileURL(path.join(modulesDir, '@seriousme', 'openapi-schema-validator', 'index.js'))));
} catch (e) {
  console.error(`@seriousme/openapi-schema-validator not found under ${modulesDir}: run docker/install-deps.sh`);
  process.exit(2);
}
const file = process.argv[2];
if (!file) {
  console.error('usage: node validate_openapi.mjs openapi.json');
  process.exit(2);
}
const result = await new Validator().validate(file);
console.log(JSON.stringify({ valid: result.valid, version: result.version ?? null, errors: result.errors ?? [] }));
process.exit(result.valid ? 0 : 1);

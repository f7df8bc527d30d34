// Runs the Khronos glTF validator on each file given and prints one JSON line
// per file: {"file", "errors", "warnings", "messages":[...first 20 errors/warnings]}.
// Exit code 0 when no file has errors, 1 otherwise, 2 on usage/IO problems.
import { createRequire } from 'module';
import fs from 'fs';
import path from 'path';

const require = createRequire(import.meta.url);
const modulesDir = process.env.RIGPORT_TOOLS_DIR
  ? path.join(process.env.RIGPORT_TOOLS_DIR, 'node_modules')
  : path.join(path.dirname(new URL(import.meta.url).pathname), '..', '..', '.tools', 'node_modules');
let validator;
try {
  validator = require(path.join(modulesDir, 'gltf-validator'));
} catch (e) {
  console.error(`gltf-validator not found under ${modulesDir}: run docker/install-deps.sh`);
  process.exit(2);
}

const files = process.argv.slice(2);
if (files.length === 0) {
  console.error('usage: node validate_gltf.mjs FILE.glb...');
  process.exit(2);
}
let failed = false;
for (const file of files) {
  let bytes;
  try {
    bytes = new Uint8Array(fs.readFileSync(file));
  } catch (e) {
    console.error(`${file}: ${e.message}`);
    process.exit(2);
  }
  const report = await validator.validateBytes(bytes, {
    uri: path.basename(file),
    maxIssues: 0,
    externalResourceFunction: () => Promise.reject(new Error('external resources are not allowed')),
  });
  const issues = report.issues;
  const messages = issues.messages
    .filter((m) => m.severity <= 1)
    .slice(0, 20)
    .map((m) => `${m.severity === 0 ? 'ERROR' : 'WARNING'} ${m.code} ${m.pointer ?? ''}: ${m.message}`);
  console.log(JSON.stringify({ file, errors: issues.numErrors, warnings: issues.numWarnings, messages }));
  if (issues.numErrors > 0) failed = true;
}
process.exit(failed ? 1 : 0);

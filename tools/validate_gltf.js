// Validate a glTF binary with the Khronos validator (installed by scripts/setup.sh into tools/node).
// Usage: node tools/validate_gltf.js FILE.glb  -> prints {errors, warnings, messages} as JSON.
const path = require('path');
const fs = require('fs');
const validator = require(path.join(__dirname, 'node', 'node_modules', 'gltf-validator'));
const data = new Uint8Array(fs.readFileSync(process.argv[2]));
validator.validateBytes(data).then((report) => {
  console.log(JSON.stringify({errors: report.issues.numErrors, warnings: report.issues.numWarnings,
    messages: report.issues.messages.map(m => m.severity + ' ' + m.code + ' ' + m.message + ' ' + m.pointer)}));
}).catch((e) => { console.error(String(e)); process.exit(1); });

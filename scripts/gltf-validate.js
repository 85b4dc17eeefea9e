// Validates a glTF/GLB file with the Khronos validator; prints the report; exits 1 on errors.
const fs = require('fs');
const path = require('path');

// The validator is installed by scripts/setup.sh under $NEURAL_CLOTH_TOOLS (default /var/tmp/neural-cloth-tools).
const tools = process.env.NEURAL_CLOTH_TOOLS || '/var/tmp/neural-cloth-tools';
const validator = require(path.join(tools, 'node_modules', 'gltf-validator'));
const file = process.argv[2];
const data = new Uint8Array(fs.readFileSync(file));
validator.validateBytes(data, {
  uri: path.basename(file),
  externalResourceFunction: (uri) => new Promise((resolve, reject) => {
    try { resolve(new Uint8Array(fs.readFileSync(path.join(path.dirname(file), decodeURIComponent(uri))))); } catch (e) { reject(e.toString()); }
  }),
}).then((report) => {
  console.log(JSON.stringify({ errors: report.issues.numErrors, warnings: report.issues.numWarnings, messages: report.issues.messages.slice(0, 30) }, null, 1));
  process.exit(report.issues.numErrors > 0 ? 1 : 0);
}).catch((e) => { console.error(e); process.exit(2); });

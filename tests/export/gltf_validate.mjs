// Validate glTF/GLB files with the Khronos glTF-Validator (npm `gltf-validator`, see package.json).
// Usage: node tests/export/gltf_validate.mjs FILE...   Prints one JSON report per file, one per line.
import { readFile } from "node:fs/promises";
import { createRequire } from "node:module";
import path from "node:path";

const require = createRequire(path.join(process.cwd(), "package.json"));
const validator = require("gltf-validator");

for (const file of process.argv.slice(2)) {
  const data = new Uint8Array(await readFile(file));
  const report = await validator.validateBytes(data, {
    uri: path.basename(file),
    maxIssues: 100,
    externalResourceFunction: () => Promise.reject(new Error("no external resources expected")),
  });
  console.log(JSON.stringify({ file, issues: report.issues }));
}

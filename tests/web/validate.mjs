// Validates glTF files with the Khronos glTF-Validator; prints one JSON line per file:
// {"file", "errors", "warnings", "infos", "messages": [first error/warning messages]}
import fs from "node:fs";
import validator from "gltf-validator";

for (const file of process.argv.slice(2)) {
  const bytes = new Uint8Array(fs.readFileSync(file));
  const report = await validator.validateBytes(bytes, { maxIssues: 200 });
  const messages = report.issues.messages
    .filter((m) => m.severity <= 1)
    .slice(0, 10)
    .map((m) => `${m.code} ${m.pointer ?? ""}: ${m.message}`);
  console.log(JSON.stringify({
    file, errors: report.issues.numErrors, warnings: report.issues.numWarnings,
    infos: report.issues.numInfos, messages,
  }));
}

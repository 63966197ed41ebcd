#!/usr/bin/env node
// Validate glTF 2.0 files (.gltf + external resources, or .glb) with the Khronos glTF-Validator
// (npm package "gltf-validator"), printing the validator's JSON reports.
//
//   node tools/gltf_validate.mjs [--strict] FILE...
//
// stdout: a JSON array with one report per FILE, in order (the validator's report object:
//         issues.numErrors / numWarnings / numInfos / numHints / messages, info, validatorVersion;
//         no timestamp, so reports are deterministic). A file that cannot be read or parsed at all
//         gets {"uri": FILE, "fatal": "<message>"} instead.
// stderr: one summary line per file.
// exit:   0 no errors (and, with --strict, no warnings), 1 some file has errors (or warnings with
//         --strict) or is fatal, 2 usage error or the validator package was not found.
//
// The package is looked up in $GLTF_VALIDATOR_DIR (the package folder), then in
// <repo>/.ci/node/node_modules/gltf-validator (what .ci/run installs), then by Node's usual
// resolution from the current directory. External resources (buffers/images referenced by a
// relative URI) are read from the folder of the .gltf file.

import { createRequire } from "node:module";
import fs from "node:fs";
import path from "node:path";
import { fileURLToPath } from "node:url";

const here = path.dirname(fileURLToPath(import.meta.url));

function loadValidator() {
  const require = createRequire(import.meta.url);
  const candidates = [];
  if (process.env.GLTF_VALIDATOR_DIR) candidates.push(path.resolve(process.env.GLTF_VALIDATOR_DIR));
  candidates.push(path.resolve(here, "..", ".ci", "node", "node_modules", "gltf-validator"));
  for (const dir of candidates) {
    if (fs.existsSync(path.join(dir, "package.json"))) return require(dir);
  }
  try {
    return require(require.resolve("gltf-validator", { paths: [process.cwd()] }));
  } catch {
    return null;
  }
}

async function validateFile(validator, file) {
  const full = path.resolve(file);
  const data = new Uint8Array(fs.readFileSync(full));
  return validator.validateBytes(data, {
    uri: path.basename(file),
    maxIssues: 0, // unlimited
    writeTimestamp: false,
    externalResourceFunction: (uri) =>
      new Promise((resolve, reject) => {
        const target = path.resolve(path.dirname(full), decodeURIComponent(uri));
        fs.readFile(target, (err, bytes) => (err ? reject(err.toString()) : resolve(new Uint8Array(bytes))));
      }),
  });
}

async function main(argv) {
  const strict = argv.includes("--strict");
  const files = argv.filter((a) => a !== "--strict");
  if (files.length === 0 || files.some((f) => f.startsWith("-"))) {
    process.stderr.write("usage: node tools/gltf_validate.mjs [--strict] FILE...\n");
    return 2;
  }
  const validator = loadValidator();
  if (!validator) {
    process.stderr.write(
      "gltf-validator not found: run `npm install --prefix .ci/node gltf-validator` " +
        "or set GLTF_VALIDATOR_DIR to the package folder\n");
    return 2;
  }
  const reports = [];
  let failed = false;
  for (const file of files) {
    let report;
    try {
      report = await validateFile(validator, file);
    } catch (err) {
      report = { uri: file, fatal: String(err && err.message ? err.message : err) };
    }
    reports.push(report);
    if (report.fatal !== undefined) {
      failed = true;
      process.stderr.write(`${file}: FATAL ${report.fatal}\n`);
      continue;
    }
    const is = report.issues;
    const bad = is.numErrors > 0 || (strict && is.numWarnings > 0);
    failed = failed || bad;
    process.stderr.write(
      `${file}: ${bad ? "FAIL" : "ok"} errors=${is.numErrors} warnings=${is.numWarnings} ` +
        `infos=${is.numInfos} hints=${is.numHints} (glTF-Validator ${report.validatorVersion})\n`);
  }
  process.stdout.write(JSON.stringify(reports, null, 2) + "\n");
  return failed ? 1 : 0;
}

main(process.argv.slice(2)).then(
  (code) => { process.exitCode = code; },
  (err) => { process.stderr.write(`gltf_validate: ${err && err.stack ? err.stack : err}\n`); process.exitCode = 2; });

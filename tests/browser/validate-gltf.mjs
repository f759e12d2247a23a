// SPDX-License-Identifier: MIT
// The Khronos glTF-Validator (npm gltf-validator, pinned in package-lock.json)
// over glTF files lodkit wrote (run by tests/cli/test_gltf_validate.sh).
// Usage: node validate-gltf.mjs FILE...   (.gltf or .glb)
// Prints one line per file: its counts of errors, warnings, infos and hints,
// then each error and warning (code, JSON pointer, message). Exits 1 if any
// file has an error or a warning or cannot be validated at all, 2 on bad usage.
import { readFile, realpath } from 'node:fs/promises';
import path from 'node:path';
import validator from 'gltf-validator';

// A .gltf's buffers and images are read relative to its folder; a URI that
// would leave the folder (../x, /etc/x, a symbolic link out) is refused, so
// the validator only ever reads what lodkit wrote beside the file.
function resourceReader(file) {
  return async (uri) => {
    // Both sides with their links resolved: a link's target is what is read.
    const folder = await realpath(path.dirname(file));
    const target = await realpath(path.resolve(folder, decodeURIComponent(uri)));
    const relative = path.relative(folder, target);
    const leaves = relative === '..' || relative.startsWith(`..${path.sep}`) || path.isAbsolute(relative);
    if (relative === '' || leaves)
      throw new Error(`${uri}: outside the folder of ${file}`);
    return new Uint8Array(await readFile(target));
  };
}

// Validates one file; returns true when it has no error and no warning.
async function validateFile(file) {
  let report;
  try {
    const bytes = new Uint8Array(await readFile(file));
    report = await validator.validateBytes(bytes, {
      uri: path.basename(file),
      maxIssues: 0, // every issue, not the first 100
      writeTimestamp: false,
      externalResourceFunction: resourceReader(file),
    });
  } catch (error) {
    // An unreadable file, or bytes that are neither glTF nor GLB.
    console.log(`${file}: cannot validate: ${error}`);
    return false;
  }
  const issues = report.issues;
  console.log(`${file}: ${issues.numErrors} errors, ${issues.numWarnings} warnings, ` +
              `${issues.numInfos} infos, ${issues.numHints} hints`);
  // Severity 0 is an error, 1 a warning (2 info, 3 hint: not failures).
  for (const message of issues.messages.filter((m) => m.severity <= 1)) {
    const kind = message.severity === 0 ? 'error' : 'warning';
    console.log(`  ${kind} ${message.code} at ${message.pointer ?? '(file)'}: ${message.message}`);
  }
  return issues.numErrors === 0 && issues.numWarnings === 0;
}

const files = process.argv.slice(2);
if (files.length === 0) {
  console.error('usage: node validate-gltf.mjs FILE... (.gltf or .glb)');
  process.exit(2);
}
let clean = true;
for (const file of files) {
  if (!(await validateFile(file))) clean = false;
}
process.exit(clean ? 0 : 1);

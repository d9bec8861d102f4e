#!/usr/bin/env node
// Validates glTF files with the Khronos glTF Validator (the npm package `gltf-validator`,
// found through NODE_PATH): prints each file's error, warning, info and hint counts and every
// error and warning, and exits 1 when any file has an error (2 when one cannot be read).
//
// Usage: NODE_PATH=<dir>/node_modules node tools/validate-gltf.cjs FILE.glb|FILE.gltf ...
'use strict';
const fs = require('fs');
const path = require('path');
const validator = require('gltf-validator');

async function validate(file) {
  const dir = path.dirname(file);
  const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(file)), {
    uri: path.basename(file),
    maxIssues: 0,
    externalResourceFunction: (uri) =>
      Promise.resolve(new Uint8Array(fs.readFileSync(path.resolve(dir, decodeURIComponent(uri))))),
  });
  const i = report.issues;
  console.log(`${file}: ${i.numErrors} errors, ${i.numWarnings} warnings, ${i.numInfos} infos, ${i.numHints} hints (glTF Validator ${report.validatorVersion})`);
  for (const m of i.messages.filter((m) => m.severity <= 1)) {
    console.log(`  ${m.severity === 0 ? 'error' : 'warning'} ${m.code} ${m.pointer || ''}: ${m.message}`);
  }
  return i.numErrors;
}

(async () => {
  const files = process.argv.slice(2);
  if (files.length === 0) {
    console.error('usage: validate-gltf.cjs FILE...');
    process.exit(2);
  }
  let errors = 0;
  for (const f of files) {
    try {
      errors += await validate(f);
    } catch (e) {
      console.error(`${f}: cannot validate: ${e}`);
      process.exit(2);
    }
  }
  process.exit(errors > 0 ? 1 : 0);
})();

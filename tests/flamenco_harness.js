// Runs the PlateLight Flamenco job type in node with stand-ins for the Manager's job compiler API
// (author.Task / author.Command / frameChunker / print), and prints what it authored as JSON.
// Usage: node flamenco_harness.js SCRIPT.js SETTINGS.json
"use strict";
const fs = require("fs");
const vm = require("vm");

const [script, settingsFile] = process.argv.slice(2);
const tasks = [];

function frameChunker(frameRange, chunkSize) {
  // A port of the Manager's jsFrameChunker (internal/manager/job_compilers/js_globals.go):
  // sorted unique frames, chunkSize at a time, each merged as "3-8,13,15,16".
  const frames = new Set();
  for (const part of `${frameRange}`.replaceAll("..", "-").split(",")) {
    const ends = part.split("-").map((x) => parseInt(x.trim(), 10));
    if (ends.length > 2 || ends.some(isNaN)) throw `invalid range "${frameRange}"`;
    for (let f = ends[0]; f <= ends[ends.length - 1]; f++) frames.add(f);
  }
  const list = [...frames].sort((a, b) => a - b);
  const merge = (chunk) => {
    const out = [];
    let start = chunk[0];
    for (let i = 1; i <= chunk.length; i++) {
      if (i === chunk.length || chunk[i] > chunk[i - 1] + 1) {
        const end = chunk[i - 1];
        if (start === end) out.push(`${start}`);
        else if (start + 1 === end) out.push(`${start}`, `${end}`);
        else out.push(`${start}-${end}`);
        start = chunk[i];
      }
    }
    return out.join(",");
  };
  const chunks = [];
  for (let i = 0; i < list.length; i += chunkSize) chunks.push(merge(list.slice(i, i + chunkSize)));
  return chunks;
}

const author = {
  Task(name, type) {
    const task = { name, type, commands: [], dependencies: [] };
    task.addCommand = (c) => task.commands.push(c);
    task.addDependency = (t) => task.dependencies.push(t.name);
    return task;
  },
  Command(type, parameters) { return { type, parameters }; },
};

const context = vm.createContext({ author, frameChunker, print: () => {}, console });
vm.runInContext(fs.readFileSync(script, "utf8") + "\n;this.JOB_TYPE = JOB_TYPE; this.compileJob = compileJob;",
                context, { filename: script });
const job = { settings: JSON.parse(fs.readFileSync(settingsFile, "utf8")), addTask: (t) => tasks.push(t) };
context.compileJob(job);
process.stdout.write(JSON.stringify({
  label: context.JOB_TYPE.label,
  settings: context.JOB_TYPE.settings.map((s) => s.key),
  tasks: tasks.map(({ name, type, commands, dependencies }) => ({ name, type, commands, dependencies })),
}));

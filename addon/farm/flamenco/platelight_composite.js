// SPDX-License-Identifier: GPL-3.0-or-later
// PlateLight for Flamenco 3: bake the probes, then render the composite in frame chunks, with the
// same commands as the Open Job Description bundle (addon/farm/jobs.py):
//     python -m platelight bake BLEND --frames A-B --quiet
//     python -m platelight render BLEND --out DIR --frames CHUNK --name NAME --format FMT --quiet
// Install: copy this file into the Flamenco Manager's `scripts/` folder (job type
// "platelight-composite"); the Workers need a Python with bpy and PlateLight installed
// (`platelight_python`), and must run "misc" tasks.

const JOB_TYPE = {
  label: "PlateLight Composite",
  description: "Bake the PlateLight probes, then render the composite onto the plate",
  settings: [
    { key: "frames", type: "string", required: true,
      eval: "f'{C.scene.frame_start}-{C.scene.frame_end}'",
      evalInfo: { showLinkButton: true, description: "Scene frame range" },
      description: "Frames to bake and render, e.g. '1-100' or '1-10, 15'" },
    { key: "chunk_size", type: "int32", default: 10, propargs: { min: 1 }, visible: "submission",
      description: "Frames per render task" },
    { key: "render_output_root", type: "string", subtype: "dir_path", required: true,
      visible: "submission", description: "Folder of the rendered frames" },
    { key: "output_name", type: "string", default: "composite", visible: "submission",
      description: "File name prefix of the frames (NAME_0001.exr)" },
    { key: "output_format", type: "string", default: "exr", choices: ["exr", "multilayer", "png"],
      visible: "submission",
      description: "exr: the composite; multilayer: the composite and named passes; png: 8-bit" },
    { key: "platelight_python", type: "string", default: "python", visible: "submission",
      description: "The Workers' Python that runs `python -m platelight` (bpy and PlateLight installed)" },
    { key: "blendfile", type: "string", required: true, visible: "web",
      description: "The .blend to bake and render" },
  ],
};

function platelight(settings, args) {
  return author.Command("exec", {
    exe: settings.platelight_python,
    args: ["-m", "platelight"].concat(args),
  });
}

function compileJob(job) {
  const settings = job.settings;
  if (!(settings.chunk_size >= 1)) {
    throw `The chunk size must be at least 1 frame, not ${settings.chunk_size}.`;
  }
  const frames = `${settings.frames}`.replace(/\s+/g, "");

  const bake = author.Task("bake-probes", "misc");
  bake.addCommand(platelight(settings, ["bake", settings.blendfile, "--frames", frames, "--quiet"]));
  job.addTask(bake);

  for (const chunk of frameChunker(frames, settings.chunk_size)) {
    const task = author.Task(`render-${chunk}`, "misc");
    task.addCommand(platelight(settings, [
      "render", settings.blendfile, "--out", settings.render_output_root,
      "--frames", `${chunk}`.replace(/\s+/g, ""), "--name", settings.output_name,
      "--format", settings.output_format, "--quiet"]));
    task.addDependency(bake);
    job.addTask(task);
  }
}

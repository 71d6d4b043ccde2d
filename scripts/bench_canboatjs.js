#!/usr/bin/env node
// Time canboat's JavaScript analyzer (canboatjs, npm @canboat/canboatjs) on the candump
// capture `cargo bench --bench can` uses: every line through FromPgn.parseString
// (candump parsing, fast-packet reassembly, decoding of every PGN it knows), best of 5.
// A second run keeps only the GNSS PGN frames (129025/129026/129029), the ones
// dash2sim decodes, so both sides decode the same messages.
//
// Usage: (cd /tmp/cbjs && npm install @canboat/canboatjs)
//        NODE_PATH=/tmp/cbjs/node_modules node scripts/bench_canboatjs.js \
//          ../shared/data/gpsd/nmea2000/logfile_20140914_365495765_can.log
// (a benchmark peer only; never a dependency of dash2sim.)
const fs = require('fs')
const { FromPgn } = require('@canboat/canboatjs')

function run(lines) {
  const parser = new FromPgn({})
  parser.on('error', () => {})
  parser.on('warning', () => {})
  let decoded = 0
  for (const line of lines) {
    if (parser.parseString(line)) decoded++
  }
  return decoded
}

function bench(name, lines) {
  const decoded = run(lines)
  let best = Infinity
  for (let i = 0; i < 5; i++) {
    const start = process.hrtime.bigint()
    run(lines)
    best = Math.min(best, Number(process.hrtime.bigint() - start) / 1e6)
  }
  console.log(`${name}: ${lines.length} frames, ${decoded} messages, best ${best.toFixed(2)} ms, ` +
    `${(lines.length / best / 1e3).toFixed(3)} M frames/s`)
}

const lines = fs.readFileSync(process.argv[2], 'latin1').split('\n').filter(l => l.startsWith('('))
const gnss = lines.filter(l => {
  const id = parseInt(l.split(' ')[2].split('#')[0], 16)
  const pgn = (id >> 8) & 0x3ffff
  return pgn === 129025 || pgn === 129026 || pgn === 129029
})
bench('canboatjs, every PGN', lines)
bench('canboatjs, GNSS frames only', gnss)

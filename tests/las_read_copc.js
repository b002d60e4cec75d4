// Reads a LAS file with the copc npm package, a LAS 1.4 reader independent of gcmap, and prints
// what it found as text for tests/test_las.cpp:
//   header MAJOR MINOR FORMAT RECORD_LENGTH COUNT MIN_X MIN_Y MIN_Z MAX_X MAX_Y MAX_Z
//   software TEXT
//   wkt TEXT
//   point X Y Z INTENSITY RETURN RETURNS CLASS SOURCE_ID GPS_TIME [RED GREEN BLUE]   (a line per point;
//   the colour in point format 7)
// Usage: NODE_PATH=DIR/node_modules node las_read_copc.js FILE
const fs = require('fs');
const { Las } = require('copc');

const buf = new Uint8Array(fs.readFileSync(process.argv[2]));
const h = Las.Header.parse(buf.slice(0, 375));
const text = (bytes) => Buffer.from(bytes).toString('latin1').replace(/\0.*$/s, '');
let wkt = '';
for (let v = 0, at = h.headerLength; v < h.vlrCount; ++v) {
  const vlr = Las.Vlr.parse(buf.slice(at, at + 54));
  if (vlr.userId === 'LASF_Projection' && vlr.recordId === 2112) wkt = text(buf.slice(at + 54, at + 54 + vlr.contentLength));
  at += 54 + vlr.contentLength;
}
const out = [];
out.push(['header', h.majorVersion, h.minorVersion, h.pointDataRecordFormat, h.pointDataRecordLength, h.pointCount, ...h.min, ...h.max].join(' '));
out.push('software ' + h.generatingSoftware);
out.push('wkt ' + wkt);
const data = buf.slice(h.pointDataOffset, h.pointDataOffset + h.pointCount * h.pointDataRecordLength);
const view = Las.View.create(data, h);
const names = ['X', 'Y', 'Z', 'Intensity', 'ReturnNumber', 'NumberOfReturns', 'Classification', 'PointSourceId', 'GpsTime'];
if (h.pointDataRecordFormat === 7) names.push('Red', 'Green', 'Blue');
const get = names.map((n) => view.getter(n));
for (let i = 0; i < view.pointCount; ++i) out.push('point ' + get.map((g) => g(i)).join(' '));
process.stdout.write(out.join('\n') + '\n');

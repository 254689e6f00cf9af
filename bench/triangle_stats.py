#!/usr/bin/env python3
"""Triangle shape statistics of a glTF file (why does ToyCar traverse slowly?).

    python3 bench/triangle_stats.py FILE.gltf   (needs numpy; glTF with an external .bin)

Per mesh: triangle count, box surface area / triangle area percentiles, box diagonal as a share
of the mesh diagonal, and how much of the summed triangle box area the long triangles hold.
"""
import json,numpy as np,sys
path=sys.argv[1]
g=json.load(open(path))
import os
buf=open(os.path.join(os.path.dirname(path),g['buffers'][0]['uri']),'rb').read()
def acc(i):
  a=g['accessors'][i]; bv=g['bufferViews'][a['bufferView']]
  off=bv.get('byteOffset',0)+a.get('byteOffset',0)
  dt={5126:np.float32,5125:np.uint32,5123:np.uint16}[a['componentType']]
  nc={'SCALAR':1,'VEC3':3,'VEC2':2,'VEC4':4}[a['type']]
  return np.frombuffer(buf,dt,a['count']*nc,off).reshape(-1,nc) if nc>1 else np.frombuffer(buf,dt,a['count'],off)
for mi,m in enumerate(g['meshes']):
  p=m['primitives'][0]; P=acc(p['attributes']['POSITION']).astype(np.float64); I=acc(p['indices']).reshape(-1,3)
  T=P[I]; e1=T[:,1]-T[:,0]; e2=T[:,2]-T[:,0]
  area=0.5*np.linalg.norm(np.cross(e1,e2),axis=1)
  lo=T.min(1); hi=T.max(1); d=hi-lo
  bsa=2*(d[:,0]*d[:,1]+d[:,1]*d[:,2]+d[:,0]*d[:,2])
  ratio=bsa/np.maximum(area,1e-30)
  diag=np.linalg.norm(d,axis=1)
  sd=np.linalg.norm(P.max(0)-P.min(0))
  print(m['name'],len(I),'degenerate',(area==0).sum(),'bboxSA/area pct50/90/99',np.percentile(ratio,[50,90,99]).round(1))
  print('  diag/scene pct 50/90/99/99.9', (np.percentile(diag,[50,90,99,99.9])/sd).round(4), 'max',diag.max()/sd)
  for f in [0.05,0.1,0.2]:
    big=diag>f*sd; print('  tris diag>%g scene:'%f,big.sum(), 'share of summed bbox SA', round(bsa[big].sum()/bsa.sum(),3))

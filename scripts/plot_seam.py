#!/usr/bin/env python3
"""A path of pieces drawn: the weld seam of client/grpcurl/plan_seam_ur5e.json (a line, a
quarter arc, a line) with and without its transition tolerance, top view and curvature
along the arc length, from the `geotraj` CLI's PlanTrajectory and AnalyzePath answers.

    plot_seam.py CLI REQUEST OUT.png
"""
import copy
import json
import subprocess
import sys

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
cli, request_file, out_file = sys.argv[1:4]
req=json.load(open(request_file))
def run(cmd, r):
    out=subprocess.run([cli,'--json',cmd,'-'],input=json.dumps(r),capture_output=True,text=True,check=True).stdout
    return json.loads(out)
def analyze(r):
    r=copy.deepcopy(r); r['analysisPoints']=2001
    return run('analyze', r)['points']
pts=analyze(req); pl=run('plan', req)
rest=copy.deepcopy(req); del rest['path']['transitionTolerance']
pts0=analyze(rest)
kinds=[s.get('kind','') for s in pl['segments']]
fig,(ax1,ax2)=plt.subplots(1,2,figsize=(11,4.2))
x0,y0=req['path']['start']['position']['x'],req['path']['start']['position']['y']
a0=[(p['position']['y']-y0)*1000 for p in pts0]; b0=[(p['position']['x']-x0)*1000 for p in pts0]
ax1.plot(b0,a0,color='k',lw=0.6,label='programmed')
for seg_i,kind in enumerate(kinds):
    ps=[p for p in pts if p.get('segment',0)==seg_i]
    a=[(p['position']['y']-y0)*1000 for p in ps]; b=[(p['position']['x']-x0)*1000 for p in ps]
    trans = kind=='SEGMENT_KIND_TRANSITION'
    ax1.plot(b,a,color='#e91e63' if trans else '#1f77b4',lw=1.6 if trans else 3,ls='--' if trans else '-',
             alpha=1.0 if trans else 0.5, label=('transition' if trans else 'exact piece') if seg_i in (0,1) else None)
ax1.set_aspect('equal'); ax1.set_xlabel('towards the start normal [mm]'); ax1.set_ylabel('along the start tangent [mm]')
ax1.set_title('weld seam: line, quarter arc r = 40 mm, line'); ax1.legend(loc='lower right',fontsize=8)
s=[p['s']*1000 for p in pts]; k=[p.get('curvature',0) for p in pts]
s0=[p['s']*1000 for p in pts0]; k0=[p.get('curvature',0) for p in pts0]
ax2.plot(s0,k0,color='k',lw=0.8,label='no tolerance: curvature steps, the motion rests')
ax2.plot(s,k,color='#e91e63',lw=1.6,label='transitionTolerance 0.1 mm: G4 transitions')
ax2.set_xlabel('arc length s [mm]'); ax2.set_ylabel('curvature [1/m]'); ax2.legend(fontsize=8,loc='lower center')
ax2.set_title('curvature along the seam (AnalyzePath)')
fig.tight_layout()
fig.savefig(out_file, dpi=90)
print(f"segments: {', '.join(k.replace('SEGMENT_KIND_', '').lower() for k in kinds)}")

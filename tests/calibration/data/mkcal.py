import numpy as np, sys
sys.path.insert(0, "/tmp/probeF/gen")
from fromcsv import load
C="/tmp/probeF/cases/cal/"
W={"A":50/4.4,"B":50/5.0}
tr={k: load(f"/tmp/probeF/out/truth{k}/curve.csv") for k in "AB"}
def rows(k, seed, noise, zero=0.0, step=0.005, irregular=0.5, jitter=2e-4, scale=1.0, slack=0.0, tare=False):
    s,f = tr[k]; rng=np.random.default_rng(seed)
    n=int(0.5/step); w=1+irregular*rng.uniform(-1,1,n); x=np.concatenate([[0],np.cumsum(w)]); x=0.5*x/x[-1]
    F = np.interp(x, s, f)*W[k]*scale
    if tare: F = F - F[0]
    S = x.copy()
    if slack:
        S = (1+S)*(1+slack)-1; sl=np.arange(0,slack,0.004)
        S=np.concatenate([sl,S]); F=np.concatenate([np.zeros(len(sl)),F])
    S = S + jitter*rng.standard_normal(len(S)); S[0]=0.0
    F = F + noise*rng.standard_normal(len(F)) + zero
    return S, F
def excel(path, S, F, percent=False, col="load_N"):
    L=["Instron Bluehill export;;;;","Specimen;EG-3;;;", ("Strain [%];" if percent else "strain;")+col+";Time;;", ("%;N;s;;" if percent else "mm/mm;N;s;;")]
    for i,(s,f) in enumerate(zip(S,F)):
        L.append((f"{s*100:.4f}" if percent else f"{s:.6f}").replace(".",",")+";"+f"{f:.5f}".replace(".",",")+f";{i*0.6:.1f}".replace(".",",")+";;")
    open(path,"wb").write(("\ufeff"+"\r\n".join(L)+"\r\n").encode())
S,F=rows("A",1,0.005); excel(C+"A_lab.csv",S,F)
S,F=rows("B",2,0.002,zero=-0.003); excel(C+"B_lab.csv",S,F)
excel(C+"B_lab_percent.csv",S,F,percent=True)
S,F=rows("A",3,0.005,slack=0.02); excel(C+"A_slack2pc.csv",S,F)
S,F=rows("A",1,0.005,zero=0.075); excel(C+"A_offset_plus15sd.csv",S,F)
S,F=rows("B",4,0.002,scale=1.2); excel(C+"B_stiffer20pc.csv",S,F)
S,F=rows("A",1,0.005,tare=True); excel(C+"A_tared.csv",S,F)
S,F=rows("B",2,0.002,tare=True); excel(C+"B_tared.csv",S,F)
print("ok")

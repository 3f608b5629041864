import numpy as np
from scipy.optimize import nnls
NC=6
KN=np.array([3.30,3.50,3.60,3.65,3.70,3.75,3.80,3.85,3.90,3.95,4.00,4.05,4.10,4.15,4.20,4.25,4.30,4.35])
def ramps(v):  # v per cell -> matrix of segment occupancy (V)
    v=np.atleast_1d(v)[:,None]
    return np.clip(v-KN[None,:-1],0,np.diff(KN)[None,:])
def fit_slopes(vs,ve,E,lam=30.0,prior=None):
    A=ramps(vs)-ramps(ve); b=np.asarray(E)
    m=A.shape[1]
    # smoothness on slopes (second difference of E ~ first diff of slope)
    D=np.zeros((m-1,m)); 
    for j in range(m-1): D[j,j]=-1; D[j,j+1]=1
    rows=[A, np.sqrt(lam)*D*0.05]; rhs=[b, np.zeros(m-1)]
    if prior is not None:  # weak pull to prior slopes where data are absent
        w=0.02; rows.append(w*np.eye(m)); rhs.append(w*prior)
    s,_=nnls(np.vstack(rows),np.concatenate(rhs))
    return s  # Wh per V(cell) per segment
def E_of(v,s): return ramps(v)@s
def fit_robust(vs,ve,E,lam=30.0,it=8,delta=0.5):
    w=np.ones(len(E))
    for _ in range(it):
        sw=np.sqrt(w)
        s=fit_slopes_w(vs,ve,E,sw,lam)
        r=np.abs(E_of(vs,s)-E_of(ve,s)-E)
        w=np.where(r<delta,1.0,delta/np.maximum(r,1e-9))
    return s
def fit_slopes_w(vs,ve,E,sw,lam):
    A=(ramps(vs)-ramps(ve))*sw[:,None]; b=np.asarray(E)*sw
    m=A.shape[1]; D=np.diff(np.eye(m),axis=0)
    s,_=nnls(np.vstack([A,np.sqrt(lam)*D*0.05]),np.concatenate([b,np.zeros(m-1)]))
    return s

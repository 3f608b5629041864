import numpy as np, pandas as pd
from load import load, PARAMS
NCELL=6
NC=6
TEST={268,269,270,271,272,273,276,277,278,279}
def flights():
    df=load()
    par=pd.read_csv(PARAMS)
    par.columns=[c.strip() for c in par.columns]
    par['local_time']=par['local_time'].astype(str).str.strip()
    par=par.set_index('flight')
    out={}
    for f,d in df.groupby('flight'):
        t=d.time.values.astype(float); V=d.battery_voltage.values.astype(float); I=d.battery_current.values.astype(float)
        on=np.where(I>1.0)[0]
        r=dict(flight=f,route=d.route.iloc[0],t=t,V=V,I=I,test=f in TEST)
        r['E_wh']=np.trapezoid(V*I,t)/3600.0
        r['Ah']=np.trapezoid(I,t)/3600.0
        if len(on)==0: r['has_on']=False
        else:
            i0,i1=on[0],on[-1]; r['has_on']=True; r['i_on']=i0; r['i_off']=i1
            pre=(t<t[i0]) & (t>=t[i0]-3.0) & (np.abs(I)<1.0)
            r['pre_len']=t[i0]-t[0]
            r['v_start']=np.median(V[pre]) if pre.sum()>=3 else np.nan
            post=(t>t[i1])
            r['post_len']=t[-1]-t[i1]
            tail=post & (t>=t[-1]-2.0) & (np.abs(I)<1.0)
            r['v_end_meas']=np.median(V[tail]) if (r['post_len']>=8 and tail.sum()>=3) else np.nan
            # slope over the last 6 s of the tail (V/s)
            s=post&(t>=t[-1]-6.0)
            r['end_slope']=np.polyfit(t[s]-t[-1],V[s],1)[0] if s.sum()>=8 and r['post_len']>=8 else np.nan
            fl=(I>3.0)
            r['I_mean_flight']=I[fl].mean() if fl.any() else 0
        p=par.loc[f]; r['date']=p['date']; hh,mm=p['local_time'].split(':'); r['tmin']=int(hh)*60+int(mm)
        out[f]=r
    # chains: next flight on same pack
    fl=sorted(out)
    for a,b in zip(fl[:-1],fl[1:]):
        A,B=out[a],out[b]; A['next']=None
        if A['date']==B['date'] and 0<B['tmin']-A['tmin']<=25 and A.get('has_on') and B.get('has_on'):
            if np.isfinite(A.get('v_end_meas',np.nan)) and np.isfinite(B.get('v_start',np.nan)):
                d=B['v_start']-A['v_end_meas']
                if -0.05<d<0.8: A['next']=b; A['gap_min']=B['tmin']-A['tmin']
    return out

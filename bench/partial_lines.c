/* The memory access pattern of 100,000 x 100 float64 rows filtered eight at
 * a time with streamed outputs, without the filtering (docs/benchmarks.md,
 * session 15): per group of eight rows, each row's head (to its first
 * line-aligned output) and tail with ordinary stores, the rest as whole
 * lines streamed past the caches, eight rows interleaved; against one
 * sequential streamed pass over the same bytes.
 *
 *   gcc -O3 -march=native bench/partial_lines.c -o /tmp/partial_lines
 *   /tmp/partial_lines MODE   # MODE bits: 1 heads, 2 tails, 4 prefetch for
 *                             # ownership of the end lines 16 rows ahead
 *
 * On the AVX-512 Xeon guest: mode 0 about 1.9-2.0 ns per sample, mode 3
 * 3.8-4.4, mode 7 2.7-2.8 (sequential 1.4-1.7): each ordinary store to a
 * line not in the caches holds up the streamed stores behind it.
 */
#include <immintrin.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
static double now(){struct timespec t;clock_gettime(CLOCK_MONOTONIC,&t);return t.tv_sec+t.tv_nsec*1e-9;}
int main(int argc,char**argv){ int mode=argc>1?atoi(argv[1]):0;
  long nt=100000, n=100; long N=nt*n;
  double *z=aligned_alloc(64,N*8), *x=aligned_alloc(64,N*8), *v=aligned_alloc(64,N*8);
  for(long i=0;i<N;i++){z[i]=i*0.5;x[i]=v[i]=0;}
  if(argc<2){fprintf(stderr,"usage: %s MODE\n",argv[0]);return 2;}
  for(int rep=0;rep<5;rep++){
    // B: sequential NT copy z->x,v
    double t0=now();
    for(long i=0;i<N;i+=8){__m512d a=_mm512_load_pd(z+i);_mm512_stream_pd(x+i,a);_mm512_stream_pd(v+i,_mm512_mul_pd(a,a));}
    _mm_sfence(); double tb=now()-t0;
    // A: groups of 8 rows, per block of 8 samples each lane loads its row segment and streams its outputs
    t0=now();
    for(long g=0;g<nt;g+=8){
      if(mode&4){ long G=g+16; if(G<nt) for(int l=0;l<8;l++){ long s=(G+l)*n; _mm_prefetch((const char*)(x+s),_MM_HINT_ET0); _mm_prefetch((const char*)(v+s),_MM_HINT_ET0); _mm_prefetch((const char*)(x+s+n-1),_MM_HINT_ET0); _mm_prefetch((const char*)(v+s+n-1),_MM_HINT_ET0);} }
      long head[8];
      for(int l=0;l<8;l++){long s=(g+l)*n; head[l]=((8-(s%8))%8);}  // samples to alignment
      if(mode&1) for(int l=0;l<8;l++){long s=(g+l)*n; for(long k=0;k<head[l];k++){x[s+k]=z[s+k];v[s+k]=z[s+k]*z[s+k];}}
      long blocks=(n-8)/8;
      for(long b=0;b<blocks;b++){
        for(int l=0;l<8;l++){long s=(g+l)*n+head[l]+b*8;
          _mm_prefetch((const char*)(z+s+64),_MM_HINT_T0);
          __m512d a=_mm512_loadu_pd(z+s);_mm512_stream_pd(x+s,a);_mm512_stream_pd(v+s,_mm512_mul_pd(a,a));}
      }
      if(mode&2) for(int l=0;l<8;l++){long s=(g+l)*n; for(long k=head[l]+blocks*8;k<n;k++){x[s+k]=z[s+k];v[s+k]=z[s+k]*z[s+k];}}
    }
    _mm_sfence(); double ta=now()-t0;
    printf("seq %.3f ns/sample, 8 rows interleaved (100) %.3f ns/sample\n", tb/N*1e9, ta/N*1e9);
  }
  return 0;
}
